"""The evaluation tests' synthetic 4 x 4 grid, whose quarter statistics are known by hand."""

import numpy as np
import pytest

from mjx_peg.evaluation.grid_table import GridTable

# A 4 x 4 synthetic grid (linear 1-4 mm, angular 1-4 deg): four ranges per quarter.
QUARTER_SUCCESS = {  # per-range success rate (%), 100 trials per range
    "Q1": [100, 98, 96, 94],
    "Q2": [96, 94, 92, 90],
    "Q3": [94, 92, 90, 88],
    "Q4": [90, 92, 95, 80],
}
QUARTER_TIME = {
    "Q1": [1.0, 1.2, 1.4, 1.6],
    "Q2": [2, 2, 2.5, 3],
    "Q3": [3, 4, 5, 6],
    "Q4": [4, 5, 6, 7],
}


@pytest.fixture
def synthetic_grid() -> GridTable:
    """The grid of QUARTER_SUCCESS and QUARTER_TIME (times min / max: mean -+ 0.5 s)."""
    linear, angular, success, times = [], [], [], []
    where = {"Q1": (0, 0), "Q2": (0, 2), "Q3": (2, 0), "Q4": (2, 2)}  # (linear, angular) offset
    for q, (li, ai) in where.items():
        for k in range(4):
            linear.append(1.0 + li + k // 2)
            angular.append(1.0 + ai + k % 2)
            success.append(QUARTER_SUCCESS[q][k])
            times.append(QUARTER_TIME[q][k])
    trials = np.full(16, 100)
    times = np.array(times, dtype=float)
    return GridTable(
        linear_mm=np.array(linear),
        angular_deg=np.array(angular),
        trials=trials,
        successes=np.array(success),
        time_mean_s=times,
        time_min_s=times - 0.5,
        time_max_s=times + 0.5,
    )


@pytest.fixture
def tiny_eval() -> list[str]:
    """eval.py's flags of a 2 x 2 grid of 4 trials per range (circle and square, 2 s), on the CPU
    engine, one range per engine call: all but --out."""
    return [
        "--policy", "baseline", "--grid", "custom", "--linear-mm", "0.5,3", "--angular-deg", "1,6",
        "--trials", "4", "--time-limit", "2", "--shape", "circle,square", "--engine", "mujoco",
        "--seed", "7", "--chunk-trials", "4", "--no-progress",
    ]  # fmt: skip
