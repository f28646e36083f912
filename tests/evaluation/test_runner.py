"""evaluation/runner.py: an evaluation runs range by range, resumes where it stopped, and gives
the same grid however it was chunked or interrupted."""

from mjx_peg.evaluation import eval_cli, runner


def test_resume_after_interruption_gives_the_same_grid(tmp_path, monkeypatch, capsys, tiny_eval):
    import multiprocessing

    full, resumed = tmp_path / "full", tmp_path / "resumed"
    assert eval_cli.main([*tiny_eval, "--out", str(full)]) == 0
    assert not multiprocessing.active_children()  # its worker processes stopped with it
    for name in ("grid.csv", "summary.md", "success_heatmap.png", "time_heatmap.png"):
        assert (full / name).stat().st_size > 0, name
    assert (full / "paper_comparison.png").stat().st_size > 0  # circle + square, 50 mm: nominal
    rows = (full / "grid.csv").read_text().splitlines()
    assert len(rows) == 5 and rows[1].startswith("0,0.5,1,Q1,4,")

    real = runner.run_trials
    calls = []

    def interrupted(specs, *args, **kwargs):
        calls.append(len(specs))
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(specs, *args, **kwargs)

    monkeypatch.setattr(runner, "run_trials", interrupted)
    assert eval_cli.main([*tiny_eval, "--out", str(resumed)]) == 130
    assert "2 of 4 ranges saved" in capsys.readouterr().err
    assert not (resumed / "grid.csv").exists()
    assert len(list((resumed / "ranges").glob("*.npz"))) == 2

    calls.clear()
    monkeypatch.setattr(runner, "run_trials", lambda *a, **k: calls.append(1) or real(*a, **k))
    assert eval_cli.main([*tiny_eval, "--out", str(resumed)]) == 0
    assert len(calls) == 2  # only the two unfinished ranges ran
    assert (resumed / "grid.csv").read_bytes() == (full / "grid.csv").read_bytes()
    # All four ranges in one engine call: the same results (chunking changes nothing).
    one_call = tmp_path / "one_call"
    assert eval_cli.main([*tiny_eval, "--chunk-trials", "1000", "--out", str(one_call)]) == 0
    assert (one_call / "grid.csv").read_bytes() == (full / "grid.csv").read_bytes()

    # A finished evaluation reruns nothing; --compare tests it against another.
    calls.clear()
    argv = [*tiny_eval, "--out", str(resumed), "--compare", str(full), "--alternative", "greater"]
    assert eval_cli.main(argv) == 0 and not calls
    summary = (resumed / "summary.md").read_text()
    assert f"## Against {full}" in summary and "after-vs-before" in summary

    # Resuming with another config is refused with one line.
    capsys.readouterr()
    assert eval_cli.main([*tiny_eval[:-1], "--no-progress", "--seed", "8", "--out", str(full)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("eval.py: error:") and "seed: 7 there, 8 now" in err
    assert len(err.splitlines()) == 1


def test_the_baseline_controller_and_a_policys_are_labelled_by_what_they_run(tmp_path):
    import hashlib

    import numpy as np

    from mjx_peg.policy.export import save_policy
    from mjx_peg.skill.baseline import baseline_params
    from mjx_peg.world.task import TaskConfig, sample_trials

    specs = sample_trials(TaskConfig(shapes=("square",)), 0, 3)
    label, controller = runner.load_controller("baseline")
    assert label == "baseline"
    np.testing.assert_array_equal(controller(specs), np.tile(baseline_params(), (3, 1)))
    layers = [(np.zeros((8, 38)), np.zeros(38))]
    save_policy(tmp_path, layers=layers, obs_mean=np.zeros(8), obs_std=np.ones(8), config={})
    label, controller = runner.load_controller(str(tmp_path))
    digest = hashlib.sha256((tmp_path / "policy.npz").read_bytes()).hexdigest()
    assert label == f"sha256:{digest}" and controller(specs).shape == (3, 38)
