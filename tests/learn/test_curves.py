"""learn/curves.py: the running mean worked out by hand, a table read back with its empty cells,
and the learning curve drawn at its size."""

from __future__ import annotations

import math

import numpy as np
from matplotlib import image

from mjx_peg.learn.curves import RUNNING_MEAN, plot_training_curve, read_table, running_mean


def test_running_mean_by_hand():
    x = np.array([4.0, 8.0, 0.0, 2.0, 6.0])
    np.testing.assert_allclose(running_mean(x, 2), [4.0, 6.0, 4.0, 1.0, 4.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(running_mean(x, 3), [4.0, 6.0, 4.0, 10 / 3, 8 / 3], rtol=1e-15)
    np.testing.assert_allclose(running_mean(x, 100), np.cumsum(x) / np.arange(1, 6), rtol=1e-15)
    np.testing.assert_array_equal(running_mean(x, 1), x)
    assert RUNNING_MEAN == 100  # the paper's Fig. 5 averages 100 trials


def test_read_table_reads_numbers_and_empty_cells_as_nan(tmp_path):
    path = tmp_path / "metrics.csv"
    path.write_text("iteration,trials,settled_rate\n1,16,\n2,32,0.25\n")
    table = read_table(path)
    assert list(table) == ["iteration", "trials", "settled_rate"]
    assert table["trials"] == [16.0, 32.0] and table["settled_rate"][1] == 0.25
    assert math.isnan(table["settled_rate"][0])


def test_the_training_curve_is_drawn_at_its_size(tmp_path):
    trials = tmp_path / "trials.csv"
    rng = np.random.default_rng(0)
    rows = [f"{t},{rng.uniform(0, 38000):.1f},{t % 2},1.5" for t in range(250)]
    trials.write_text("trial,return,success,time_s\n" + "\n".join(rows) + "\n")
    out = plot_training_curve(trials, tmp_path / "curve.png", "a test")
    assert out == tmp_path / "curve.png"
    assert image.imread(out).shape[:2] == (540, 960)  # 8 x 4.5 in at 120 dpi
