"""evaluation/eval_dir.py: an evaluation's directory, and those that earlier versions wrote."""

import numpy as np

from mjx_peg.evaluation import eval_cli, eval_dir


def test_evaluations_from_before_early_ending_read_as_full_time_limit(tmp_path, capsys, tiny_eval):
    """A config.json without full_time_limit (written before early ending) ran every failure to
    the time limit: it reads so, and resuming it needs --full-time-limit."""
    import json

    out = tmp_path / "old"
    assert eval_cli.main([*tiny_eval, "--full-time-limit", "--out", str(out)]) == 0
    assert "every failure ran to the time limit" in (out / "summary.md").read_text()
    doc = json.loads((out / "config.json").read_text())
    del doc["config"]["full_time_limit"]
    (out / "config.json").write_text(json.dumps(doc))
    config, _ = eval_dir.read_eval_dir(out)
    assert config.full_time_limit and not config.trial_config().end_settled
    assert eval_cli.main([*tiny_eval, "--full-time-limit", "--out", str(out)]) == 0
    capsys.readouterr()
    assert eval_cli.main([*tiny_eval, "--out", str(out)]) == 2
    assert "full_time_limit: True there, False now" in capsys.readouterr().err


def test_evaluations_from_before_credible_contact_are_read_but_not_resumed(
    tmp_path, capsys, tiny_eval
):
    """A config.json without contact_model (written before the F/T pipeline and the protective
    stop) ran another trial: its ranges still load (without contact metrics) and grid.csv has
    no contact values, but it is neither resumed nor replayed."""
    import json

    from mjx_peg.evaluation import demo_cli

    out = tmp_path / "old"
    assert eval_cli.main([*tiny_eval, "--out", str(out)]) == 0
    grid = (out / "grid.csv").read_text().splitlines()
    assert grid[0].endswith("settled,protective_stops,peak_force_median_n,chatter_under_5n_pct")
    assert "nan" not in grid[1].split(",")[-3]  # the peak force of the current trial
    assert "contact: peak sensed force median" in (out / "summary.md").read_text()
    doc = json.loads((out / "config.json").read_text())
    del doc["config"]["contact_model"]
    (out / "config.json").write_text(json.dumps(doc))
    for path in (out / "ranges").iterdir():
        with np.load(path) as npz:
            arrays = {k: npz[k] for k in npz.files if k not in ("chatter", "protective_stop")}
        np.savez(path, **arrays)
    config, _ = eval_dir.read_eval_dir(out)
    assert config.contact_model == 1
    assert eval_dir.grid_table(out, config).peak_force_median_n is not None
    assert np.isnan(eval_dir.grid_table(out, config).protective_stops).all()
    capsys.readouterr()
    assert eval_cli.main([*tiny_eval, "--out", str(out)]) == 2
    assert "contact_model: 1 there, 2 now" in capsys.readouterr().err
    argv = ["--replay", str(out), "--range", "0", "--trial", "0", "--out", str(tmp_path / "d")]
    assert demo_cli.main(argv) == 2
    assert "before credible contact" in capsys.readouterr().err
