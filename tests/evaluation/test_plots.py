"""evaluation/plots.py: the heatmaps (the paper's Figs. 6-7) and the quarters beside the paper's."""

import numpy as np
import pytest

from mjx_peg.evaluation.grid_table import GridTable
from mjx_peg.evaluation.paper_tables import PAPER
from mjx_peg.evaluation.plots import (
    grid_matrix,
    paper_bars,
    quarter_stats_by_metric,
    success_heatmap,
    time_heatmap,
)


def test_heatmaps_are_written(tmp_path, synthetic_grid):
    grid = synthetic_grid
    matrix, linear, angular = grid_matrix(grid, grid.success_pct)
    assert matrix.shape == (4, 4) and list(linear) == [1, 2, 3, 4]
    assert matrix[0, 0] == 100.0  # bottom left = smallest errors = Q1
    t = grid.time_mean_s.copy()
    t[0] = np.nan  # a range without a success
    grid = GridTable(**{**grid.__dict__, "time_mean_s": t})
    for fn, name in ((success_heatmap, "s.png"), (time_heatmap, "t.png")):
        path = fn(grid, tmp_path / name)
        data = path.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    means, mins, maxes = quarter_stats_by_metric(grid)["success"]
    assert means[0] == pytest.approx(97.0) and mins[0] <= means[0] <= maxes[0]
    for condition in ("nominal", "triangle"):  # the triangle has no paper times: one panel
        path = paper_bars(grid, PAPER[condition], tmp_path / f"{condition}.png", condition)
        data = path.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
