"""robot/ur5e_cli.py (`python -m mjx_peg.robot --robot-ip / --rehearse / --dry-run`): the plan,
the rehearsal on the simulated UR5e and its log, and the real-arm path's one-line refusals."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from mjx_peg.engines.trial import TrialConfig
from mjx_peg.errors import UsageError
from mjx_peg.robot import cli, ur5e_cli
from mjx_peg.robot.runtime import HoleEstimate
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world import constants
from mjx_peg.world.kinematics import fk_tcp


def test_a_hole_is_given_in_mm_mm_deg():
    assert ur5e_cli.parse_hole("450,-120,30") == pytest.approx((0.45, -0.12, math.pi / 6))
    for text in ("450,-120", "450,-120,30,1", "a,b,c", "450,nan,30", "450,inf,0"):
        with pytest.raises(UsageError, match="--hole must be"):
            ur5e_cli.parse_hole(text)


def test_the_plan_starts_above_the_hole_and_the_dmp_ends_at_its_goal():
    """Start 60 mm above the board top over the hole, the goal on the table top at the hole's
    centre, both reached by their joint configurations (DH kinematics) within 1e-6 m, and the
    DMP's free motion straight down from the one to the other, within 0.1 mm."""
    hole = HoleEstimate(0.45, -0.12, math.radians(30), "circle", 0.05)
    p = ur5e_cli.plan(hole, baseline_params(), TrialConfig())
    np.testing.assert_allclose(p["start_pos"], [0.45, -0.12, constants.HOLE_DEPTH + 0.06])
    np.testing.assert_allclose(p["goal_pos"], [0.45, -0.12, constants.GOAL_HEIGHT], atol=1e-12)
    for q, pos in ((p["q_start"], p["start_pos"]), (p["q_goal"], p["goal_pos"])):
        tcp, rot = fk_tcp(q, constants.PEG_LENGTH)
        np.testing.assert_allclose(tcp, pos, atol=1e-6)
        np.testing.assert_allclose(rot, p["rot"], atol=1e-6)
    np.testing.assert_allclose(p["path"][0], p["start_pos"], atol=1e-9)
    np.testing.assert_allclose(p["path"][-1], p["goal_pos"], atol=1e-4)
    np.testing.assert_allclose(p["path"][:, :2], np.broadcast_to([0.45, -0.12], (len(p["t"]), 2)),
                               atol=1e-9)  # straight down the hole's axis  # fmt: skip
    with pytest.raises(UsageError, match="out of the UR5e's reach"):
        ur5e_cli.plan(HoleEstimate(2.0, 0.0, 0.0, "circle", 0.05), baseline_params(), TrialConfig())


def test_cli_rehearsal_inserts_and_writes_its_log(tmp_path, capsys):
    argv = ["--rehearse", "--hole", "450,-120,30", "--shape", "square", "--time-limit", "5",
            "--out", str(tmp_path)]  # fmt: skip
    assert cli.main(argv) == 0
    out = capsys.readouterr().out
    assert "baseline on the UR5e at sim" in out and "inserted at" in out
    rows = (tmp_path / "ur5e_run.csv").read_text().splitlines()
    header = rows[0].split(",")
    assert header[:3] == ["t_s", "period_ms", "work_ms"] and header[-1] == "sent"
    assert "wrench_fz" in header and "goal_z" in header and "tau6" in header
    assert 200 < len(rows) - 1 < 2500
    assert (tmp_path / "ur5e_run.png").stat().st_size > 10_000
    assert cli.main(argv) == 2  # an earlier run is kept without --force
    assert "--force" in capsys.readouterr().err


def test_cli_dry_run_prints_the_plan_and_connects_to_nothing(capsys):
    assert cli.main(["--dry-run", "--hole", "450,-120,30", "--shape", "circle"]) == 0
    out = capsys.readouterr().out
    assert "move (moveJ) to the start (450.0, -120.0, 140.0) mm" in out
    assert "t =  2.00 s  tcp (450.0, -120.0, -0.0) mm" in out or "-120.0, 0.0) mm" in out
    assert "nothing was connected or moved" in out


@pytest.mark.parametrize(
    "argv, message",
    [
        (
            ["--robot-ip", "127.0.0.1", "--hole", "450,-120,30"],
            "cannot connect to a UR5e at 127.0.0.1",
        ),
        (["--robot-ip", "not an ip!", "--hole", "1,2,3"], "not an IP address or host name"),
        (["--robot-ip", "127.0.0.1"], "need --hole X,Y,YAW"),
        (["--dry-run", "--hole", "450,-120"], "--hole must be X,Y,YAW"),
        (["--dry-run", "--hole", "2000,0,0"], "out of the UR5e's reach"),
        (["--shadow", "--hole", "450,0,0"], "need --robot-ip, --rehearse or --dry-run"),
        (["--rehearse", "--robot-ip", "127.0.0.1", "--hole", "450,0,0"], "drop --robot-ip"),
        (["--robot-ip", "127.0.0.1", "--hole", "450,0,0", "--command-hz", "125"], "500 Hz only"),
    ],
)
def test_cli_real_arm_bad_input_is_one_line(argv, message, tmp_path, capsys):
    code = cli.main([*argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and message in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "out").exists()  # nothing written before the input is accepted


@pytest.mark.parametrize(
    "mode",
    [
        ["--dry-run"],
        ["--rehearse"],
        ["--shadow", "--robot-ip", "127.0.0.1"],
        ["--robot-ip", "127.0.0.1"],
    ],  # fmt: skip
)
@pytest.mark.parametrize(
    "policy, part, message",
    [
        (
            "transfer",
            ["--shape", "circle"],
            "--policy transfer was trained on triangle, not circle",
        ),
        ("paper", ["--shape", "triangle"], "was trained on circle, square, not triangle"),
        ("paper", ["--shape", "circle", "--size", "25"], "trained at S = 50 mm, not 25 mm"),
    ],
)
def test_cli_refuses_a_shipped_policy_on_a_part_it_was_not_trained_for(
    mode, policy, part, message, tmp_path, capsys
):
    """The shipped manifests as written (config.shapes, config.size_mm), on every real-arm
    path, before a plan is printed, a connection tried or anything written."""
    argv = [*mode, "--policy", policy, *part, "--hole", "450,-120,30"]
    assert cli.main([*argv, "--out", str(tmp_path / "out")]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and message in captured.err and len(captured.err.splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_cli_runs_a_shipped_policy_on_the_part_it_was_trained_for(capsys):
    argv = ["--dry-run", "--policy", "transfer", "--shape", "triangle", "--hole", "450,-120,30"]
    assert cli.main(argv) == 0
    assert "nothing was connected or moved" in capsys.readouterr().out


@pytest.mark.parametrize("mode", [[], ["--rehearse", "--hole", "450,-120,30"]])
def test_cli_never_writes_into_the_folder_of_the_policy_it_reads(
    mode, tmp_path, monkeypatch, capsys
):
    """--out is compared with --policy as resolved folders: a shipped policy's name, a link to
    its folder and a relative path to it are all the same folder."""
    import shutil

    from mjx_peg.policy import shipped

    copy = tmp_path / "policies"
    shutil.copytree(shipped.SHIPPED_DIR / "paper", copy / "paper")
    monkeypatch.setattr(shipped, "SHIPPED_DIR", copy)
    (tmp_path / "link").symlink_to(copy / "paper")
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in (copy / "paper").iterdir())
    for out in ("link", "policies/paper", str(copy / "paper"), "policies"):
        argv = [*mode, "--policy", "paper", "--shape", "circle", "--trials", "1", "--out", out]
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert "an output never replaces an input" in err and len(err.splitlines()) == 1, err
    assert sorted(p.name for p in (copy / "paper").iterdir()) == before


def test_without_ur_rtde_the_package_imports_and_the_cli_says_how_to_install(tmp_path):
    code = (
        "import sys\n"
        "for m in ('rtde_control', 'rtde_receive', 'dashboard_client'):\n"
        "    sys.modules[m] = None\n"
        "import mjx_peg.robot.ur5e, mjx_peg.robot.runtime\n"
        "from mjx_peg.robot import cli\n"
        "argv = ['--robot-ip', '127.0.0.1', '--hole', '450,0,0', '--out', sys.argv[1]]\n"
        "sys.exit(cli.main(argv))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True
    )
    assert done.returncode == 2, done.stderr
    assert 'pip install -e ".[robot]"' in done.stderr and len(done.stderr.splitlines()) == 1
