"""evaluation/grid_table.py: the per-range table of a grid, from its trials and in grid.csv."""

import numpy as np
import pytest

from mjx_peg.evaluation.grid_table import GRID_COLUMNS, GridTable


def test_grid_csv_round_trip(tmp_path, synthetic_grid):
    grid = synthetic_grid
    path = tmp_path / "grid.csv"
    path.write_text(grid.csv_text())
    header = path.read_text().splitlines()[0].split(",")
    assert header == list(GRID_COLUMNS)
    back = GridTable.from_csv(path)
    np.testing.assert_array_equal(back.successes, grid.successes)
    np.testing.assert_allclose(back.time_mean_s, grid.time_mean_s)
    np.testing.assert_array_equal(back.quarter, grid.quarter)
    with pytest.raises(ValueError, match="not an evaluation grid.csv"):
        (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
        GridTable.from_csv(tmp_path / "bad.csv")
    with pytest.raises(ValueError, match="is missing: not a finished evaluation"):
        GridTable.from_csv(tmp_path / "absent.csv")


def test_a_table_from_per_trial_results_by_hand():
    """Two ranges of four trials: success rates, times over the successes, contact metrics."""
    first = {
        "success": np.array([True, True, False, True]),
        "time_s": np.array([2.0, 4.0, 60.0, 3.0]),
        "settled": np.array([False, False, True, False]),
        "protective_stop": np.array([False, False, False, False]),
        "peak_force": np.array([10.0, 30.0, 20.0, 40.0]),
        "chatter": np.array([1.0, 9.0, 2.0, 3.0]),  # trials over 1.2 s: 3 of 4 under 5 N
    }
    second = {  # saved before the contact metrics: none of them
        "success": np.array([False, False, False, False]),
        "time_s": np.array([60.0, 60.0, 1.0, 60.0]),
        "settled": np.array([True, True, False, False]),
        "peak_force": np.array([1.0, 1.0, 1.0, 1.0]),
    }
    table = GridTable.from_ranges([(1.0, 2.0), (3.0, 4.0)], [first, second])
    np.testing.assert_array_equal(table.linear_mm, [1.0, 3.0])
    np.testing.assert_array_equal(table.successes, [3, 0])
    np.testing.assert_allclose(table.success_pct, [75.0, 0.0])
    np.testing.assert_allclose(table.time_mean_s, [3.0, np.nan])
    np.testing.assert_allclose(table.time_min_s, [2.0, np.nan])
    np.testing.assert_allclose(table.time_max_s, [4.0, np.nan])
    np.testing.assert_array_equal(table.settled, [1, 2])
    np.testing.assert_allclose(table.protective_stops, [0.0, np.nan])
    np.testing.assert_allclose(table.peak_force_median_n, [25.0, np.nan])
    np.testing.assert_allclose(table.chatter_under_5n_pct, [75.0, np.nan])
