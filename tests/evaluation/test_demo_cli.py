"""evaluation/demo_cli.py (`mjx-peg-demo`): one trial watched and one of an evaluation replayed."""

from __future__ import annotations

import numpy as np
import pytest

from mjx_peg.evaluation import demo_cli, eval_cli
from mjx_peg.evaluation import eval_dir as evaluation

# on one xdist worker, which runs the module's evaluation once (spread over two, each ran it)
pytestmark = pytest.mark.xdist_group("demo_cli")

EVAL = [
    "--policy", "baseline", "--grid", "custom", "--linear-mm", "1,2", "--angular-deg", "3",
    "--trials", "6", "--time-limit", "4", "--shape", "circle,square", "--engine", "mujoco",
    "--seed", "3", "--no-progress",
]  # fmt: skip


@pytest.fixture(scope="module")
def eval_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("eval")
    assert eval_cli.main([*EVAL, "--out", str(out)]) == 0
    return out


def test_replay_ends_as_the_evaluation_recorded(eval_dir, tmp_path, capsys):
    config, _ = evaluation.read_eval_dir(eval_dir)
    recorded = evaluation.load_range(eval_dir, config, 1)
    assert recorded["success"].any() and not recorded["success"].all()  # both kinds to pick
    for kind in ("success", "failure"):
        index = int(np.flatnonzero(recorded["success"] == (kind == "success"))[0])
        out = tmp_path / kind
        argv = ["--replay", str(eval_dir), "--range", "1", "--trial", kind, "--out", str(out)]
        assert demo_cli.main([*argv, "--frames", "2"]) == 0
        text = capsys.readouterr().out
        assert f"range 1 (±2 mm / ±3 deg) trial {index}:" in text
        then = f"{kind} after {recorded['time_s'][index]:.3f} s"
        assert f"replay: {then}; the evaluation: {then} (the same)" in text
        assert (out / "trial.png").stat().st_size > 0 and (out / "frames.png").stat().st_size > 0


def test_replay_reports_a_different_outcome(eval_dir, tmp_path, capsys, monkeypatch):
    """If the replay does not end as recorded (here: the evaluation's record is altered), the
    demo says so and exits 1."""
    real = evaluation.load_range

    def altered(out, config, index):
        arrays = real(out, config, index)
        arrays["time_s"] = arrays["time_s"] + 0.5
        return arrays

    monkeypatch.setattr(evaluation, "load_range", altered)
    argv = ["--replay", str(eval_dir), "--range", "0", "--frames", "0", "--out", str(tmp_path)]
    assert demo_cli.main(argv) == 1
    assert "(DIFFERENT)" in capsys.readouterr().out


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--range", "2"], "--replay needs --range between 0 and 1, got 2"),
        (["--range", "0", "--trial", "6"], "--trial must be failure, success or an index below 6"),
        (["--range", "0", "--shape", "square"], "--replay takes the trial from the evaluation"),
        (["--range", "0", "--time-limit", "5"], "drop --time-limit"),
    ],
)
def test_bad_replay_is_one_clear_line(eval_dir, tmp_path, capsys, extra, message):
    argv = ["--replay", str(eval_dir), *extra, "--out", str(tmp_path / "o")]
    assert demo_cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"{demo_cli.PROG}: error:"), err
    assert message in err, err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--replay", "NO_DIR", "--range", "0"], "holds no config.json"),
        (["--range", "0"], "--range and --trial need --replay EVAL_DIR"),
        (["--policy", "NO_DIR"], "no such run directory, and no shipped policy"),
        (["--size", "-5"], "--size must be a number in [10, 100] mm, got -5"),
    ],
)
def test_bad_input_is_one_clear_line(tmp_path, capsys, argv, message):
    argv = [str(tmp_path / "nope") if a == "NO_DIR" else a for a in argv]
    assert demo_cli.main([*argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err


def test_demo_with_a_policy_directory(tmp_path, capsys):
    """--policy RUN_DIR drives the trial with the policy's 38 numbers for that trial."""
    from mjx_peg.policy.export import load_policy, save_policy

    rng = np.random.default_rng(0)
    layers = [(0.1 * rng.normal(size=(8, 16)), np.zeros(16)), (np.zeros((16, 38)), np.zeros(38))]
    save_policy(
        tmp_path / "run", layers=layers, obs_mean=np.zeros(8), obs_std=np.ones(8), config={}
    )
    argv = ["--policy", str(tmp_path / "run"), "--time-limit", "0.2", "--frames", "0"]
    assert demo_cli.main([*argv, "--out", str(tmp_path / "o")]) == 0
    assert capsys.readouterr().out.startswith("square 50 mm, ±3 mm / ±4 deg: ")
    args = demo_cli.build_parser().parse_args(argv)
    specs, vector, config, _ = demo_cli.trial_from_args(args)
    assert config.time_limit_s == 0.2
    np.testing.assert_array_equal(vector, load_policy(tmp_path / "run").controller_vectors(specs))
