"""The statistics of an evaluation: the paper's quarters, Mann-Whitney U tests, McNemar's test.

The paper divides the error plane into quarters (section 6.2): Q1 small linear & small angular
("bottom left" in its figures), Q2 small linear & large angular ("upper left"), Q3 large linear &
small angular ("bottom right"), Q4 both large ("upper right"). Each axis is split at its middle:
the first n // 2 of its n distinct ranges are "small" (25 linear ranges: 12 small, 13 large).

Tests between quarters or grids are one-sided Mann-Whitney U tests on per-range values,
significance level ALPHA = 0.05, as in the paper. The U statistic of x against y counts the pairs
in which x is larger, a tie counting one half:

    U_x = sum_i sum_j [x_i > y_j] + 1/2 [x_i = y_j],    U_x + U_y = n_x n_y

(scipy.stats.mannwhitneyu, method "auto": the exact distribution of U for small samples without
ties, else the normal approximation with tie correction and continuity correction). Success
rates are per range in percent; times are per-range means of the time to complete over successful
trials (s), ranges without a success left out.

Paired successes of two runs on the same trials (a vision estimate against the sampled error)
are compared by McNemar's exact test: with b trials that only the first run inserts and c that
only the second does, p = P(|B - (b + c)/2| >= |b - (b + c)/2|) for B ~ Binomial(b + c, 1/2).
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
from scipy import stats

from mjx_peg.errors import UsageError

ALPHA = 0.05  # the paper's significance level
QUARTERS: tuple[str, ...] = ("Q1", "Q2", "Q3", "Q4")
# Every unordered pair of quarters; each is tested in both one-sided directions.
QUARTER_PAIRS: tuple[tuple[str, str], ...] = tuple(itertools.combinations(QUARTERS, 2))
METRICS = ("success", "time")  # success rate per range (%), mean time to complete per range (s)
HIGHER_IS_BETTER = {"success": True, "time": False}


def quarter_labels(linear, angular) -> np.ndarray:
    """(R,) quarter name per range from (R,) linear and angular ranges (any units).

    Each axis splits at its middle: the first n // 2 of its n sorted distinct values are small.
    """
    linear, angular = np.asarray(linear, dtype=float), np.asarray(angular, dtype=float)
    if linear.shape != angular.shape or linear.ndim != 1:
        raise UsageError(f"linear {linear.shape} and angular {angular.shape} must be equal 1-D")

    def large(values: np.ndarray) -> np.ndarray:
        axis = np.unique(values)
        return np.searchsorted(axis, values) >= len(axis) // 2

    index = 2 * large(linear).astype(int) + large(angular).astype(int)  # Q1=0, Q2=1, Q3=2, Q4=3
    return np.asarray(QUARTERS)[index]


@dataclasses.dataclass(frozen=True)
class QuarterStats:
    """Mean, min and max of per-range values in one quarter (NaN when it has none)."""

    n: int
    mean: float
    min: float
    max: float


def quarter_stats(values, quarters) -> dict[str, QuarterStats]:
    """Per-quarter statistics of (R,) per-range values; NaN values (no data) are left out."""
    values, quarters = np.asarray(values, dtype=float), np.asarray(quarters)
    out = {}
    for q in QUARTERS:
        v = values[(quarters == q) & np.isfinite(values)]
        if v.size:
            out[q] = QuarterStats(int(v.size), float(v.mean()), float(v.min()), float(v.max()))
        else:
            out[q] = QuarterStats(0, math.nan, math.nan, math.nan)
    return out


@dataclasses.dataclass(frozen=True)
class UTest:
    """One-sided Mann-Whitney U test of sample x against sample y."""

    alternative: str  # "greater": x tends to be larger than y; "less"; "two-sided"
    u: float  # U statistic of x (number of pairs with x > y, ties counting one half)
    p: float  # p-value (NaN when a sample is empty)
    n_x: int
    n_y: int

    @property
    def significant(self) -> bool:
        return bool(self.p < ALPHA)


def mann_whitney(x, y, alternative: str) -> UTest:
    """scipy.stats.mannwhitneyu on the finite values of x and y; NaN p if a sample is empty."""
    if alternative not in ("greater", "less", "two-sided"):
        raise UsageError(f"alternative must be greater, less or two-sided, got {alternative!r}")
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    x, y = x[np.isfinite(x)], y[np.isfinite(y)]
    if x.size == 0 or y.size == 0:
        return UTest(alternative, math.nan, math.nan, int(x.size), int(y.size))
    res = stats.mannwhitneyu(x, y, alternative=alternative, method="auto")
    return UTest(alternative, float(res.statistic), float(res.pvalue), int(x.size), int(y.size))


@dataclasses.dataclass(frozen=True)
class OrderTest:
    """Both one-sided tests between two quarters and what they conclude."""

    first: str
    second: str
    better: UTest  # alternative: `first` performs better (higher success / shorter time)
    worse: UTest  # alternative: `first` performs worse

    def conclusion(self) -> tuple[str, str] | None:
        """(better quarter, worse quarter) if either one-sided test is significant, else None."""
        if self.better.significant:
            return (self.first, self.second)
        if self.worse.significant:
            return (self.second, self.first)
        return None


def quarter_order_tests(values, quarters, metric: str) -> list[OrderTest]:
    """Each pair of quarters tested in both one-sided directions (the paper's quarters' order).

    metric "success": better = higher success rate; "time": better = shorter time.
    """
    if metric not in METRICS:
        raise UsageError(f"metric must be one of {METRICS}, got {metric!r}")
    values, quarters = np.asarray(values, dtype=float), np.asarray(quarters)
    up, down = ("greater", "less") if HIGHER_IS_BETTER[metric] else ("less", "greater")
    tests = []
    for a, b in QUARTER_PAIRS:
        x, y = values[quarters == a], values[quarters == b]
        tests.append(OrderTest(a, b, mann_whitney(x, y, up), mann_whitney(x, y, down)))
    return tests


def compare_quarters(values, quarters, other_values, other_quarters, alternative: str):
    """Per quarter: Mann-Whitney U test of this grid's values against another grid's.

    alternative as in scipy ("less": this grid's values tend to be smaller). -> {quarter: UTest}
    """
    values, quarters = np.asarray(values, dtype=float), np.asarray(quarters)
    other_values, other_quarters = np.asarray(other_values, dtype=float), np.asarray(other_quarters)
    return {
        q: mann_whitney(values[quarters == q], other_values[other_quarters == q], alternative)
        for q in QUARTERS
    }


def mcnemar_p(a, b) -> float:
    """Two-sided exact McNemar p-value of paired successes a, b: (N,) bool each."""
    a, b = np.asarray(a, dtype=bool), np.asarray(b, dtype=bool)
    if a.shape != b.shape:
        raise UsageError(f"paired successes must have one shape, got {a.shape} and {b.shape}")
    only_a, only_b = int(np.sum(a & ~b)), int(np.sum(~a & b))
    if only_a + only_b == 0:
        return 1.0
    return float(stats.binomtest(only_a, only_a + only_b, 0.5).pvalue)
