"""evaluation/stats.py: quarters, Mann-Whitney U tests and McNemar's test, against statistics
worked out by hand (the exact null distributions counted over all rank sets)."""

import math

import numpy as np
import pytest

from mjx_peg.evaluation import stats as es
from mjx_peg.evaluation.config import PRESETS
from mjx_peg.evaluation.grid_table import GridTable

Q1, Q4 = [100, 98, 96, 94], [90, 92, 95, 80]  # the synthetic grid's (conftest.py)
SUCCESS = {"Q1": Q1, "Q2": [96, 94, 92, 90], "Q3": [94, 92, 90, 88], "Q4": Q4}


def test_quarters_split_each_axis_at_its_middle(synthetic_grid):
    grid = synthetic_grid
    for q in es.QUARTERS:
        np.testing.assert_array_equal(
            np.sort(grid.success_pct[grid.quarter == q]), np.sort(SUCCESS[q])
        )
    # The paper grid: 25 linear ranges (12 small), 14 angular (7 small, up to 6 deg).
    lin, ang, trials = PRESETS["paper"]
    assert (len(lin), len(ang), trials) == (25, 14, 200)
    assert lin[0] == pytest.approx(0.32) and lin[-1] == pytest.approx(8.0)
    assert ang[0] == pytest.approx(12 / 14) and ang[-1] == pytest.approx(12.0)
    ll, aa = np.meshgrid(lin, ang, indexing="ij")
    quarters = es.quarter_labels(ll.ravel(), aa.ravel())
    counts = {q: int((quarters == q).sum()) for q in es.QUARTERS}
    assert counts == {"Q1": 12 * 7, "Q2": 12 * 7, "Q3": 13 * 7, "Q4": 13 * 7}
    assert set(quarters[(ll.ravel() < 4.0) & (aa.ravel() <= 6.0 + 1e-9)]) == {"Q1"}


def test_quarter_statistics_by_hand(synthetic_grid):
    grid = synthetic_grid
    stats = es.quarter_stats(grid.success_pct, grid.quarter)
    assert stats["Q1"] == es.QuarterStats(4, 97.0, 94.0, 100.0)
    assert stats["Q4"] == es.QuarterStats(4, 89.25, 80.0, 95.0)
    times = es.quarter_stats(grid.time_mean_s, grid.quarter)
    assert times["Q2"].mean == pytest.approx(2.375) and times["Q3"].max == 6.0
    # Ranges without a success have no time: left out, and a quarter without data is NaN.
    t = grid.time_mean_s.copy()
    t[grid.quarter == "Q3"] = np.nan
    t[np.flatnonzero(grid.quarter == "Q1")[0]] = np.nan
    stats = es.quarter_stats(t, grid.quarter)
    assert stats["Q1"].n == 3 and stats["Q1"].mean == pytest.approx(1.4)
    assert stats["Q3"].n == 0 and math.isnan(stats["Q3"].mean)


def test_mann_whitney_exact_by_hand():
    """Q1 [100, 98, 96, 94] vs Q4 [90, 92, 95, 80]: 15 of 16 pairs favour Q1, no ties.

    Exact null distribution: of the C(8, 4) = 70 equally likely rank sets, one gives U = 16 and
    one U = 15, so P(U >= 15) = 2 / 70.
    """
    test = es.mann_whitney(Q1, Q4, "greater")
    assert test.u == 15.0 and (test.n_x, test.n_y) == (4, 4)
    assert test.p == pytest.approx(2 / 70, rel=1e-12)
    assert test.significant
    # The other direction: P(U' <= 1) ... U' = 16 - 15 = 1 for Q4, P(U_Q4 >= 1) = 69 / 70.
    other = es.mann_whitney(Q4, Q1, "greater")
    assert other.u == 1.0 and other.p == pytest.approx(69 / 70, rel=1e-12)
    assert not other.significant
    # Smallest case: [3] vs [1, 2] has U = 2 of 2, exact p = 1 / 3.
    assert es.mann_whitney([3.0], [1.0, 2.0], "greater").p == pytest.approx(1 / 3)
    assert es.mann_whitney([3.0], [1.0, 2.0], "less").p == pytest.approx(1.0)


def test_mann_whitney_ties_normal_approximation_by_hand():
    """Success rates tie often: scipy falls back to the normal approximation, tie-corrected."""
    x, y = [100.0, 100.0, 98.0, 96.0, 96.0], [98.0, 96.0, 94.0, 94.0]
    # U_x: 100 beats all 4 (x2) = 8; 98 beats 96, 94, 94 and ties 98 = 3.5; each 96 beats
    # 94, 94 and ties 96 = 2.5 (x2) -> U = 16.5.
    u = 8 + 3.5 + 2 * 2.5
    n1, n2 = len(x), len(y)
    n = n1 + n2
    ties = [2, 2, 3, 2]  # 100 x2, 98 x2, 96 x3, 94 x2
    sigma = math.sqrt(n1 * n2 / 12 * ((n + 1) - sum(t**3 - t for t in ties) / (n * (n - 1))))
    z = (u - n1 * n2 / 2 - 0.5) / sigma  # continuity correction
    p = 0.5 * math.erfc(z / math.sqrt(2))
    test = es.mann_whitney(x, y, "greater")
    assert test.u == u
    assert test.p == pytest.approx(p, rel=1e-10)
    # Identical samples: nothing to conclude; empty samples: NaN, never an exception.
    assert es.mann_whitney([100.0] * 3, [100.0] * 4, "greater").p == pytest.approx(1.0)
    assert math.isnan(es.mann_whitney([], [1.0], "greater").p)
    assert math.isnan(es.mann_whitney([np.nan], [1.0], "less").p)


def test_quarter_order_and_comparison_tests(synthetic_grid):
    grid = synthetic_grid
    tests = {
        (t.first, t.second): t
        for t in es.quarter_order_tests(grid.success_pct, grid.quarter, "success")
    }
    assert set(tests) == set(es.QUARTER_PAIRS) and len(tests) == 6
    assert tests[("Q1", "Q4")].better.p == pytest.approx(2 / 70)
    assert tests[("Q1", "Q4")].conclusion() == ("Q1", "Q4")
    assert tests[("Q3", "Q4")].conclusion() is None
    # Time: better means shorter. Q1 times are all below Q4's: U = 0, p = 1 / 70 for "less".
    times = {
        (t.first, t.second): t
        for t in es.quarter_order_tests(grid.time_mean_s, grid.quarter, "time")
    }
    assert times[("Q1", "Q4")].better.u == 0.0
    assert times[("Q1", "Q4")].better.p == pytest.approx(1 / 70)
    assert times[("Q1", "Q4")].conclusion() == ("Q1", "Q4")
    # Against another grid: every success rate 10 points lower -> "less" in every quarter.
    worse = GridTable(**{**grid.__dict__, "successes": grid.successes - 10})
    result = es.compare_quarters(
        worse.success_pct, worse.quarter, grid.success_pct, grid.quarter, "less"
    )
    assert set(result) == set(es.QUARTERS)
    # Q1 [90, 88, 86, 84] vs [100, 98, 96, 94]: U = 0 -> p = 1 / 70.
    assert result["Q1"].u == 0.0 and result["Q1"].p == pytest.approx(1 / 70)


def test_mann_whitney_u_counts_the_pairs_a_sample_wins():
    """x = [3, 5, 7, 9], y = [1, 2, 4, 6]: 3 beats 2 of y, 5 beats 3, 7 and 9 beat all 4: U = 13
    of 16. The rank sum of x is U + 4 * 5 / 2 = 23; of the C(8, 4) = 70 rank sets, those summing
    to 23 or more are {5,6,7,8} (26), {4,6,7,8} (25), {3,6,7,8}, {4,5,7,8} (24), {2,6,7,8},
    {3,5,7,8}, {4,5,6,8} (23): P(U >= 13) = 7 / 70; P(U <= 13) = 1 - P(U >= 14) = 66 / 70."""
    greater = es.mann_whitney([3, 5, 7, 9], [1, 2, 4, 6], "greater")
    assert greater.u == 13.0 and greater.p == pytest.approx(7 / 70, rel=1e-12)
    assert not greater.significant  # 0.1 > ALPHA = 0.05
    less = es.mann_whitney([3, 5, 7, 9], [1, 2, 4, 6], "less")
    assert less.u == 13.0 and less.p == pytest.approx(66 / 70, rel=1e-12)
    with pytest.raises(ValueError, match="alternative must be greater, less or two-sided"):
        es.mann_whitney([1.0], [2.0], "bigger")


def test_mcnemar_by_hand():
    """Exact McNemar: only the b discordant pairs count, B ~ Binomial(b + c, 1/2), two-sided."""
    first = np.array([1, 1, 1, 1, 1, 0, 1, 1, 0, 0], bool)  # 5 only here, 1 only in second
    second = np.array([0, 0, 0, 0, 0, 1, 1, 1, 0, 0], bool)
    # P(B <= 1) = (1 + 6) / 64 for n = 6; two-sided: 14 / 64
    assert es.mcnemar_p(first, second) == pytest.approx(14 / 64, rel=1e-12)
    assert es.mcnemar_p(second, first) == pytest.approx(14 / 64, rel=1e-12)
    # 7 against 0: 2 / 2^7
    assert es.mcnemar_p(np.ones(7, bool), np.zeros(7, bool)) == pytest.approx(1 / 64, rel=1e-12)
    # No discordant pair: nothing to tell apart.
    assert es.mcnemar_p(first, first) == 1.0
    with pytest.raises(ValueError, match="paired successes must have one shape"):
        es.mcnemar_p(first, first[:3])
