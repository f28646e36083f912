"""evaluation/eval_cli.py: `python eval.py`, its policies, its skill and its one-line errors."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mjx_peg.evaluation import eval_cli, eval_dir
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


def test_the_skill_is_the_policys_unless_given_and_old_evaluations_read_as_paper(tmp_path):
    import json

    from mjx_peg.policy.export import save_policy

    run = tmp_path / "run"
    layers = [(np.zeros((8, 38)), np.zeros(38))]
    save_policy(run, layers=layers, obs_mean=np.zeros(8), obs_std=np.ones(8),
                config={"skill": "search"})  # fmt: skip
    argv = [
        "--policy", str(run), "--grid", "custom", "--linear-mm", "1", "--angular-deg", "1",
        "--trials", "1", "--time-limit", "0.2", "--shape", "square", "--engine", "mujoco",
        "--no-progress",
    ]  # fmt: skip
    for extra, skill in (([], "search"), (["--skill", "paper"], "paper")):
        out = tmp_path / f"eval_{skill}"
        assert eval_cli.main([*argv, *extra, "--out", str(out)]) == 0
        assert json.loads((out / "config.json").read_text())["config"]["skill"] == skill
        assert f"skill: {skill} (" in (out / "summary.md").read_text()
    config, _ = eval_dir.read_eval_dir(tmp_path / "eval_search")
    assert config.trial_config().search.centre_gain > 0
    doc = json.loads((out / "config.json").read_text())
    del doc["config"]["skill"]  # written before the contact search
    (out / "config.json").write_text(json.dumps(doc))
    config, _ = eval_dir.read_eval_dir(out)
    assert config.skill == "paper" and not config.trial_config().search.active
    assert policy_skill("baseline") == "paper"


@pytest.mark.parametrize(
    "change, message",
    [
        ({"--policy": "EMPTY_DIR"}, "holds no policy.npz"),
        ({"--linear-mm": ""}, "--linear-mm is empty"),
        ({"--angular-deg": "5:1:1"}, "--angular-deg is empty"),
        ({"--trials": "-3"}, "--trials must be an integer in 1..100,000, got -3"),
        ({"--shape": "hexagon"}, "unknown shape 'hexagon'"),
        ({"--linear-mm": "80"}, "--linear-mm ranges must lie in [0, 50] mm, got 80"),
        ({"--compare": "NO_DIR"}, "nope does not exist"),
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
