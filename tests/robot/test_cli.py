"""robot/cli.py (`python -m mjx_peg.robot`): trials on the simulated arm, runs.csv and skill.json,
the command rate as physics steps, and one-line errors."""

from __future__ import annotations

import json
import re

import pytest

from mjx_peg.errors import UsageError
from mjx_peg.robot import cli
from mjx_peg.skill.search import SKILLS, NamedSkill


def test_cli_runs_and_reports(tmp_path, capsys):
    argv = ["--trials", "2", "--time-limit", "0.5", "--command-hz", "250", "--no-progress"]
    assert cli.main([*argv, "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "baseline on the simulated arm at 250 Hz commands, circle 50 mm" in out
    rows = (tmp_path / "runs.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[1].split(",")[3] == "125"  # 0.5 s at 250 Hz, not inserted
    # the skill the trials ran, every constant: the baseline's, the paper's
    skill = json.loads((tmp_path / "skill.json").read_text())
    assert skill == NamedSkill("paper", SKILLS["paper"]).record()


def test_a_skill_constant_set_is_the_skill_the_trials_run(tmp_path, capsys):
    """--skill-constant sets that constant of the skill the trials run (skill.json records it);
    a value the skill refuses is one line, exit 2, and nothing is written."""
    constants = ["--skill-constant", "spiral_yaw=0.1", "--skill-constant", "spiral_yaw_period=1"]
    argv = ["--trials", "1", "--time-limit", "0.2", "--no-progress", "--skill", "spiral",
            *constants]  # fmt: skip
    assert cli.main([*argv, "--out", str(tmp_path / "run")]) == 0
    skill = json.loads((tmp_path / "run" / "skill.json").read_text())
    wanted = SKILLS["spiral"].replace(spiral_yaw=0.1, spiral_yaw_period=1.0)
    assert skill == NamedSkill("spiral", wanted).record()
    capsys.readouterr()
    code = cli.main(["--skill-constant", "spiral_yaw=1", "--out", str(tmp_path / "refused")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "SkillConfig.spiral_yaw must be in [0, 0.3] rad" in err
    assert len(err.splitlines()) == 1 and not (tmp_path / "refused").exists()


@pytest.mark.parametrize(
    "hz, steps", [(500.0, 1), (250.0, 2), (500.0 / 3, 3), (125.0, 4), (100.0, 5), (1.0, 500)]
)
def test_a_command_rate_is_a_whole_number_of_physics_steps(hz, steps):
    assert cli.command_steps(hz) == steps


@pytest.mark.parametrize(
    "hz, limit, message",
    [
        (300.0, 60.0, "must divide the 500 Hz physics"),
        (166.0, 60.0, "must divide the 500 Hz physics"),  # 166.7 Hz is 3 steps; 166 is not
        (0.0, 60.0, "must be in (0, 500]"),
        (501.0, 60.0, "must be in (0, 500]"),
        (float("nan"), 60.0, "must be in (0, 500]"),
        (1.0, 0.5, "commands every 1 s, longer than the --time-limit of 0.5 s"),
    ],
)
def test_a_command_rate_the_physics_cannot_give_is_refused(hz, limit, message):
    with pytest.raises(UsageError, match=re.escape(message)):
        cli.command_steps(hz, limit)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--command-hz", "300"], "--command-hz must divide the 500 Hz physics"),
        (["--command-hz", "0"], "--command-hz must be a number in (0, 500] Hz, got 0"),
        (["--trials", "0"], "--trials must be an integer in 1..100,000, got 0"),
        (["--policy", "no/such/run"], "--policy no/such/run: no such run directory"),
        (["--size", "-5"], "--size must be a number in [10, 100] mm, got -5"),
        (["--time-limit", "nan"], "--time-limit must be a number in [0.01, 600] s, got 'nan'"),
        (["--shape", "octagon"], "argument --shape: invalid choice"),
        (["--hole-scale", "loose"], "--hole-scale must be paper or tight or a number in [1.01,"),
    ],
)
def test_cli_bad_input_is_one_line(argv, message, tmp_path, capsys):
    code = cli.main([*argv, "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and message in err and len(err.splitlines()) == 1
