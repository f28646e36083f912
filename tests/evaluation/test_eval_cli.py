"""evaluation/eval_cli.py: `python eval.py`, its policies, its skill and its one-line errors."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mjx_peg.evaluation import eval_cli, eval_dir, runner
from mjx_peg.policy.export import policy_skill

REPO = Path(__file__).resolve().parents[2]


def test_learned_policy_directory(tmp_path):
    from mjx_peg.policy.export import save_policy

    rng = np.random.default_rng(0)
    run = tmp_path / "run"
    layers = [
        (0.1 * rng.normal(size=(8, 16)), np.zeros(16)),
        (0.1 * rng.normal(size=(16, 38)), np.zeros(38)),
    ]
    save_policy(run, layers=layers, obs_mean=np.zeros(8), obs_std=np.ones(8), config={})
    out = tmp_path / "eval"
    argv = [
        "--policy", str(run), "--grid", "custom", "--linear-mm", "1", "--angular-deg", "1",
        "--trials", "2", "--time-limit", "0.5", "--shape", "square", "--engine", "mujoco",
        "--no-progress", "--out", str(out),
    ]  # fmt: skip
    assert eval_cli.main(argv) == 0
    import json

    config = json.loads((out / "config.json").read_text())
    assert config["config"]["policy"].startswith("sha256:")
    assert config["policy_dir"] == str(run.resolve())
    assert (out / "grid.csv").read_text().count("\n") == 2
    # a shipped policy is recorded by its name, which every checkout resolves
    argv[argv.index(str(run))], argv[-1] = "paper", str(tmp_path / "eval_shipped")
    assert eval_cli.main(argv) == 0
    shipped = json.loads((tmp_path / "eval_shipped" / "config.json").read_text())
    assert shipped["policy_dir"] == "paper"


def test_the_skill_is_the_policys_unless_given_and_old_evaluations_read_as_they_ran(tmp_path):
    """Without --skill an evaluation runs the skill the policy's manifest names (a manifest
    without one: the skill it was trained with, here `search` of an earlier version, its
    constants as they were); config.json records the name and every constant. Evaluations
    written before constants were recorded read as the named skill's (`search`, `align`: as
    they were; none named: the paper's) and resume."""
    import json

    from mjx_peg.file_versions import FORMER_SKILLS
    from mjx_peg.policy.export import save_policy
    from mjx_peg.skill.search import SKILLS, NamedSkill, SkillConfig, constants_record

    run = tmp_path / "run"
    layers = [(np.zeros((8, 38)), np.zeros(38))]
    save_policy(run, layers=layers, obs_mean=np.zeros(8), obs_std=np.ones(8),
                config={"skill": "search"})  # fmt: skip
    manifest = json.loads((run / "manifest.json").read_text())
    del manifest["skill"]  # written before manifests named the skill to run them with
    (run / "manifest.json").write_text(json.dumps(manifest))
    argv = [
        "--policy", str(run), "--grid", "custom", "--linear-mm", "1", "--angular-deg", "1",
        "--trials", "1", "--time-limit", "0.2", "--shape", "square", "--engine", "mujoco",
        "--no-progress",
    ]  # fmt: skip
    search = SkillConfig(centre_gain=1.0)  # the centring alone
    runs = (([], "search", search), (["--skill", "spiral"], "spiral", SKILLS["spiral"]))
    for extra, skill, constants in runs:
        out = tmp_path / f"eval_{skill}"
        assert eval_cli.main([*argv, *extra, "--out", str(out)]) == 0
        recorded = json.loads((out / "config.json").read_text())["config"]
        assert recorded["skill"] == skill
        assert recorded["skill_constants"] == constants_record(constants)
        assert len(recorded["skill_constants"]) == len(SkillConfig.__dataclass_fields__)
        assert f"skill: {skill} (" in (out / "summary.md").read_text()
    assert SkillConfig(**FORMER_SKILLS["search"]) == search
    # An evaluation of an earlier version: no constants, or no skill at all.
    for name, expected in (("align", search.replace(align_rate=1.0)), (None, SKILLS["paper"])):
        doc = json.loads((out / "config.json").read_text())
        doc["config"].pop("skill_constants", None)
        if name is None:
            del doc["config"]["skill"]  # written before the contact search
        else:
            doc["config"]["skill"] = name
        (out / "config.json").write_text(json.dumps(doc))
        config, _ = eval_dir.read_eval_dir(out)
        assert config.skill == (name or "paper") and config.trial_config().search == expected
        assert eval_dir.prepare_out_dir(out, config) == out  # resumed as it is
    assert policy_skill("baseline") == NamedSkill("paper", SKILLS["paper"])


def test_a_rerun_whose_skill_constants_changed_is_refused(tmp_path, monkeypatch, capsys, tiny_eval):
    """The skill's constants are part of the evaluation's config: after one constant of the
    spiral changed, the same command refuses in one line naming --out and the constant, and
    runs and writes nothing (no old ranges resumed beside new ones)."""
    from mjx_peg.skill import search

    out = tmp_path / "spiral"
    argv = [*tiny_eval, "--linear-mm", "1", "--angular-deg", "1", "--skill", "spiral", "--out",
            str(out)]  # fmt: skip
    assert eval_cli.main(argv) == 0
    before = {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    changed = search.SKILLS["spiral"].replace(spiral_speed=0.04)
    monkeypatch.setitem(search.SKILLS, "spiral", changed)
    calls = []
    monkeypatch.setattr(runner, "run_trials", lambda *a, **k: calls.append(1))
    capsys.readouterr()
    assert eval_cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"--out {out}" in err
    assert "skill_constants.spiral_speed: 0.03 there, 0.04 now" in err
    assert not calls
    assert {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()} == before


def test_a_skill_constant_set_runs_as_the_skill_with_it(tmp_path, monkeypatch, tiny_eval):
    """`--skill-constant NAME=VALUE` runs the trials the skill with that constant would run
    (the same grid.csv; the movement's duration changed, so not the default skill's),
    config.json records it, summary.md names it, and a rerun without it is refused rather than
    resumed."""
    import json

    from mjx_peg.skill import search

    argv = [*tiny_eval, "--linear-mm", "1", "--angular-deg", "1", "--skill", "spiral"]
    flagged = tmp_path / "flagged"
    assert eval_cli.main([*argv, "--skill-constant", "movement_s=0.8", "--out",
                          str(flagged)]) == 0  # fmt: skip
    recorded = json.loads((flagged / "config.json").read_text())["config"]["skill_constants"]
    assert recorded["movement_s"] == 0.8
    assert "movement_s=0.8 set; its constants in config.json" in (
        flagged / "summary.md").read_text()  # fmt: skip
    assert eval_cli.main([*argv, "--out", str(flagged)]) == 2  # another config there
    assert eval_cli.main([*argv, "--out", str(tmp_path / "default")]) == 0
    with monkeypatch.context() as m:
        m.setitem(search.SKILLS, "spiral", search.SKILLS["spiral"].replace(movement_s=0.8))
        assert eval_cli.main([*argv, "--out", str(tmp_path / "skill")]) == 0
    flag, default, skill = ((tmp_path / d / "grid.csv").read_text()
                            for d in ("flagged", "default", "skill"))  # fmt: skip
    assert flag == skill != default and flag.count("\n") == 2


@pytest.mark.parametrize(
    "change, message",
    [
        ({"--policy": "EMPTY_DIR"}, "holds no policy.npz"),
        ({"--linear-mm": ""}, "--linear-mm is empty"),
        ({"--angular-deg": "5:1:1"}, "--angular-deg is empty"),
        ({"--trials": "-3"}, "--trials must be an integer in 1..100,000, got -3"),
        ({"--shape": "octagon"}, "unknown shape 'octagon'"),
        ({"--linear-mm": "80"}, "--linear-mm ranges must lie in [0, 50] mm, got 80"),
        ({"--compare": "NO_DIR"}, "nope does not exist"),
        ({"--skill-constant": "pitch=1"}, "must be NAME=VALUE with NAME a constant of the skill"),
        ({"--skill-constant": "spiral_tilt=1"}, "SkillConfig.spiral_tilt must be in [0, 0.15]"),
    ],
)
def test_bad_input_is_one_clear_line(tmp_path, capsys, change, message, tiny_eval):
    (tmp_path / "empty").mkdir()
    argv = [*tiny_eval, "--out", str(tmp_path / "out")]
    for key, value in change.items():
        value = {"EMPTY_DIR": str(tmp_path / "empty"), "NO_DIR": str(tmp_path / "nope")}.get(
            value, value
        )
        if key in argv:
            argv[argv.index(key) + 1] = value
        else:
            argv += [key, value]
    assert eval_cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("eval.py: error:") and message in err, err
    assert not (tmp_path / "out" / "ranges").exists()


def test_cli_script(tmp_path):
    """`python eval.py`: --help works; bad input exits non-zero with one line, no traceback."""
    run = subprocess.run(
        [sys.executable, "eval.py", "--help"], cwd=REPO, capture_output=True, text=True
    )
    assert run.returncode == 0 and "--grid" in run.stdout and "--compare" in run.stdout
    run = subprocess.run(
        [sys.executable, "eval.py", "--policy", str(tmp_path), "--out", str(tmp_path / "o")],
        cwd=REPO,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        f"eval.py: error: {tmp_path} holds no policy.npz: not a run directory with a policy"
    ]
