"""learn/run_dir.py: the run directory's tables cut back to a checkpoint's trial count on resume,
an older metrics.csv given the columns added since, and the plan for new, resumed, finished and
replaced runs."""

from __future__ import annotations

import csv
import json

import pytest

from mjx_peg.errors import UsageError
from mjx_peg.learn.config import TrainConfig
from mjx_peg.learn.run_dir import METRICS_COLUMNS, TRIALS_COLUMNS, RunDir

CONFIG = TrainConfig(trials=12, num_envs=4, time_limit_s=0.5)


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.reader(f))


def _three_iterations(run: RunDir, columns=METRICS_COLUMNS) -> None:
    """Iterations 1-3 of 4 trials each: metrics rows at 4, 8 and 12 trials, trials 0-11."""
    for it in range(1, 4):
        metrics = {"iteration": it, "trials": 4 * it}
        row = [metrics.get(name, 0.25 * it) for name in columns]
        trials = [[t, 100.0 * t, int(t % 2), 0.5] for t in range(4 * (it - 1), 4 * it)]
        run.append(row, trials)


def test_a_resume_cuts_the_tables_back_to_the_checkpoints_trials(tmp_path):
    run = RunDir(tmp_path)
    run.start_tables()
    _three_iterations(run)
    assert len(_rows(run.metrics_path)) == 4 and len(_rows(run.trials_path)) == 13
    run.truncate_tables(8)  # the checkpoint after iteration 2 holds 8 trials
    metrics, trials = _rows(run.metrics_path), _rows(run.trials_path)
    assert metrics[0] == list(METRICS_COLUMNS) and trials[0] == list(TRIALS_COLUMNS)
    assert [r[1] for r in metrics[1:]] == ["4", "8"]
    assert [r[0] for r in trials[1:]] == [str(t) for t in range(8)]
    assert trials[8] == ["7", "700.0", "1", "0.5"]
    run.truncate_tables(0)
    assert len(_rows(run.metrics_path)) == 1 and len(_rows(run.trials_path)) == 1


def test_a_half_written_row_is_dropped_and_missing_tables_are_started(tmp_path):
    run = RunDir(tmp_path)
    run.start_tables()
    _three_iterations(run)
    with open(run.trials_path, "a") as f:
        f.write("12,12")  # a row cut off when the run was killed
    run.truncate_tables(12)
    assert [r[0] for r in _rows(run.trials_path)[1:]] == [str(t) for t in range(12)]
    run.trials_path.unlink()
    run.truncate_tables(8)  # a table is missing: both start again
    assert _rows(run.metrics_path) == [list(METRICS_COLUMNS)]
    assert _rows(run.trials_path) == [list(TRIALS_COLUMNS)]


def test_an_older_metrics_table_gets_the_columns_added_since_empty(tmp_path):
    run = RunDir(tmp_path)
    older = [c for c in METRICS_COLUMNS if c not in ("settled_rate", "chatter_median_n")]
    run.start_tables()
    with open(run.metrics_path, "w", newline="") as f:
        csv.writer(f).writerow(older)
    _three_iterations(run, older)
    run.truncate_tables(12)
    metrics = _rows(run.metrics_path)
    assert metrics[0] == list(METRICS_COLUMNS) and len(metrics) == 4
    for name in ("settled_rate", "chatter_median_n"):
        i = metrics[0].index(name)
        assert [r[i] for r in metrics[1:]] == ["", "", ""]
    i = metrics[0].index("success_rate")
    assert [r[i] for r in metrics[1:]] == ["0.25", "0.5", "0.75"]


def test_a_table_that_does_not_read_is_one_line_naming_it(tmp_path):
    run = RunDir(tmp_path)
    run.start_tables()
    _three_iterations(run)
    run.metrics_path.write_text("iteration,trials\n1,four\n")
    with pytest.raises(UsageError, match="metrics.csv is corrupt") as error:
        run.truncate_tables(8)
    assert str(run.metrics_path) in str(error.value) and len(str(error.value).splitlines()) == 1


def test_the_plan_for_a_run_directory(tmp_path):
    """Absent: new; prepared with a config: resumed with it, refused with another; finished:
    refused unless forced, which replaces it."""
    run = RunDir(tmp_path / "run")
    assert run.plan(CONFIG, force=False) == "new"
    run.prepare(CONFIG, "new")
    assert run.read_config() == CONFIG and not run.is_finished()
    assert run.plan(CONFIG, force=False) == "resume"
    with pytest.raises(UsageError, match="trials"):
        run.plan(CONFIG.replace(trials=16), force=False)
    run.manifest_path.write_text(json.dumps({"finished": True}))
    assert run.is_finished()
    with pytest.raises(UsageError, match="holds a finished run; pass --force"):
        run.plan(CONFIG, force=False)
    assert run.plan(CONFIG, force=True) == "replace"
    with pytest.raises(UsageError, match="is not a training run"):
        RunDir(tmp_path).read_config()
