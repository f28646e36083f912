"""learn/seeds.py: a set of runs over seeds, aggregated per trial count (mean, std, min, max)."""

import csv

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.learn import seeds
from mjx_peg.learn.curves import read_table
from mjx_peg.learn.run_dir import EVAL_COLUMNS, METRICS_COLUMNS, TRIALS_COLUMNS


def _write(path, columns, rows):
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        writer.writerows(rows)


def _run(base, seed, success, returns, held=None):
    """A run directory of two iterations of 4 trials: its success per iteration, its returns."""
    run = base / f"seed-{seed}"
    run.mkdir(parents=True)
    blank = [""] * (len(METRICS_COLUMNS) - 4)
    _write(run / "metrics.csv", METRICS_COLUMNS,
           [[i + 1, 4 * (i + 1), 0.0, s, *blank] for i, s in enumerate(success)])  # fmt: skip
    _write(run / "trials.csv", TRIALS_COLUMNS, [[i, r, 0, ""] for i, r in enumerate(returns)])
    if held is not None:
        _write(run / "eval.csv", EVAL_COLUMNS, [[2, 8, held, 0.0, "", 0.0]])


def test_the_set_is_aggregated_per_trial_count_over_its_seeds(tmp_path):
    _run(tmp_path, 0, [0.25, 0.5], [0, 0, 0, 0, 38000, 0, 0, 38000], held=0.5)
    _run(tmp_path, 1, [0.5, 1.0], [38000] * 8, held=1.0)
    (tmp_path / "seed-x").mkdir()  # not a seed's run
    runs, rows = seeds.aggregate(tmp_path)
    assert list(runs) == [0, 1]
    assert [r["trials"] for r in rows] == [4, 8]
    last = rows[-1]
    assert last["success_rate_mean"] == pytest.approx(0.75)
    assert last["success_rate_std"] == pytest.approx(0.25)
    assert (last["success_rate_min"], last["success_rate_max"]) == (0.5, 1.0)
    # the running mean of the returns over every trial so far (fewer than 100)
    assert last["return_running_mean_mean"] == pytest.approx((9500 + 38000) / 2)
    assert rows[0]["eval_success_rate_seeds"] == 0 and last["eval_success_rate_seeds"] == 2
    line = seeds.summarize(tmp_path)
    assert line.startswith("2 seeds (0, 1), 8 trials") and "held-out success" in line
    table = read_table(tmp_path / "seeds.csv")
    np.testing.assert_allclose(table["success_rate_mean"], [0.375, 0.75])
    assert (tmp_path / "seeds.png").stat().st_size > 10_000


def test_a_folder_without_seed_runs_is_one_clear_error(tmp_path):
    with pytest.raises(UsageError, match="no seed-N run directory"):
        seeds.aggregate(tmp_path)
    with pytest.raises(UsageError, match="is not a directory"):
        seeds.aggregate(tmp_path / "absent")
    assert seeds.main([str(tmp_path)]) == 2
