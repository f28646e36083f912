"""Quarter statistics of an evaluation grid and the paper's reference numbers (Tables 4-5).

The paper divides the error plane into quarters (section 6.2): Q1 small linear & small angular
("bottom left" in its figures), Q2 small linear & large angular ("upper left"), Q3 large linear &
small angular ("bottom right"), Q4 both large ("upper right"). Each axis is split at its middle:
the first n // 2 of its n distinct ranges are "small" (25 linear ranges: 12 small, 13 large).

Tests are one-sided Mann-Whitney U tests (scipy.stats.mannwhitneyu, method "auto": exact for
small samples without ties, else the normal approximation with continuity correction) on
per-range values, significance level ALPHA = 0.05, as in the paper. Success rates are per range
in percent; times are per-range means of the time to complete over successful trials (s), ranges
without a success left out.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import itertools
import math
from pathlib import Path

import numpy as np
from scipy import stats

from mjx_peg import cli, inputs
from mjx_peg.errors import UsageError

MAX_GRID_CSV_BYTES = 64 * 2**20  # a grid.csv of 10,000 ranges is ~1.5 MB
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


# ---------------------------------------------------------------------------------------------
# The paper's numbers, transcribed from paper/spector-zacksenhouse-compliant-dmp.tex: Table 4
# (tab:summary results, success rate %) and Table 5 (tab:summary results time, s), and the
# tests stated only in the text of sections 6.3 (60 / 25 mm against nominal).


@dataclasses.dataclass(frozen=True)
class PaperQuarters:
    """Mean, min and max over ranges per quarter (Q1..Q4)."""

    mean: tuple[float, float, float, float]
    min: tuple[float, float, float, float]
    max: tuple[float, float, float, float]


@dataclasses.dataclass(frozen=True)
class PaperCondition:
    """One column block of the paper's Tables 4-5."""

    title: str
    grid: str  # how the paper evaluated it
    success: PaperQuarters
    time: PaperQuarters | None  # Table 5 has no time for the unseen triangle (6.4)
    # (better, worse) quarter pairs the paper found significant ("Quarters' order" rows);
    # None where the paper reports no quarter-order test.
    success_order: frozenset[tuple[str, str]] | None
    time_order: frozenset[tuple[str, str]] | None
    # Per quarter: success rate significantly below nominal (None: not stated).
    below_nominal: tuple[bool | None, ...] | None = None
    # Per quarter: success rate significantly higher after re-training than before.
    after_vs_before: tuple[bool | None, ...] | None = None


def _order(rows: dict[str, str]) -> frozenset[tuple[str, str]]:
    """{"Q1": "2,3,4"} (the tables' "> 2,3,4") -> {("Q1","Q2"), ("Q1","Q3"), ("Q1","Q4")}."""
    return frozenset((q, f"Q{k}") for q, ks in rows.items() for k in ks.split(",") if q[1:] != k)


PAPER: dict[str, PaperCondition] = {
    "nominal": PaperCondition(
        title="Section 6.2, nominal performance (S = 50 mm, circle and square)",
        grid="350 ranges x 200 trials",
        success=PaperQuarters(
            (96.96, 94.22, 91.83, 87.83), (92, 87.5, 83.5, 77.5), (99.5, 99.0, 96.5, 96.5)
        ),
        time=PaperQuarters(
            (1.9, 2.72, 4.34, 4.88), (1.46, 1.69, 1.94, 2.48), (3.16, 4.76, 7.17, 7.23)
        ),
        success_order=_order({"Q1": "2,3,4", "Q2": "3,4", "Q3": "4"}),
        time_order=_order({"Q1": "2,3,4", "Q2": "3,4", "Q3": "4"}),
    ),
    "60mm": PaperCondition(
        title="Section 6.3, generalization to S = 60 mm",
        grid="100 ranges x 50 trials",
        success=PaperQuarters((96.88, 92, 91.2, 83.52), (92, 80, 78, 72), (100, 96, 98, 98)),
        time=PaperQuarters(
            (2.57, 3.01, 5.92, 6.67), (1.1, 1.37, 2.5, 2.6), (5.11, 6.13, 9.72, 12.97)
        ),
        success_order=_order({"Q1": "2,3,4", "Q2": "4", "Q3": "4"}),
        time_order=_order({"Q1": "3,4", "Q2": "3,4"}),
        # Text of 6.3: no significant difference in Q1 and Q3, significant in Q2 and Q4.
        below_nominal=(False, True, False, True),
    ),
    "25mm": PaperCondition(
        title="Section 6.3, generalization to S = 25 mm",
        grid="100 ranges x 50 trials",
        success=PaperQuarters(
            (94.45, 91.5, 93.8, 92.05), (86.25, 85, 86.25, 85), (98.75, 98.75, 98.75, 98.75)
        ),
        time=PaperQuarters(
            (2.87, 4.47, 3.09, 4.42), (0.57, 1, 1.16, 2.33), (5.54, 8.32, 6.29, 7.08)
        ),
        success_order=_order({"Q1": "2,4", "Q3": "2,4"}),
        time_order=_order({"Q1": "2,4", "Q3": "2,4"}),
        # Text of 6.3: significantly lower in Q1 and Q2; Q3 and Q4 not stated.
        below_nominal=(True, True, None, None),
    ),
    "triangle": PaperCondition(
        title="Section 6.4, generalization to the unseen triangle (nominal policy)",
        grid="100 ranges x 50 trials",
        success=PaperQuarters((75.44, 68.8, 75.68, 63.68), (66, 46, 62, 52), (86, 82, 86, 78)),
        time=None,
        success_order=None,
        time_order=None,
        below_nominal=(True, True, True, True),
    ),
    "transfer": PaperCondition(
        title="Section 6.5, triangle after transfer learning",
        grid="100 ranges x 50 trials",
        success=PaperQuarters((97, 87.5, 86, 78), (90, 65, 65, 45), (100, 100, 100, 95)),
        time=PaperQuarters(
            (1.3, 2.87, 3.12, 4.96), (0.7, 0.93, 0.8, 0.98), (2.94, 5.15, 6.09, 10.33)
        ),
        # Table 4 prints "> 1,2,3,4" for Q1; a quarter cannot beat itself, so read "> 2,3,4".
        success_order=_order({"Q1": "2,3,4", "Q2": "4", "Q3": "4"}),
        time_order=_order({"Q1": "2,3,4", "Q2": "4", "Q3": "4"}),
        below_nominal=(False, True, True, True),
        after_vs_before=(True, True, True, True),
    ),
}
PAPER_CONDITIONS: tuple[str, ...] = tuple(PAPER)


def paper_condition_for(shapes, size_mm: float) -> str | None:
    """The paper's condition matching an evaluation's shapes and size, or None."""
    shapes = set(shapes)
    if shapes == {"triangle"} and math.isclose(size_mm, 50.0):
        return "triangle"
    if not shapes <= {"circle", "square"}:
        return None
    for name, size in (("nominal", 50.0), ("60mm", 60.0), ("25mm", 25.0)):
        if math.isclose(size_mm, size):
            return name
    return None


def paper_order_conclusion(order, a: str, b: str) -> str:
    """The paper's finding for quarters a, b: 'Qa better', 'Qb better', 'n.s.' or '-' (none)."""
    if order is None:
        return "-"
    if (a, b) in order:
        return f"{a} better"
    if (b, a) in order:
        return f"{b} better"
    return "n.s."


# ---------------------------------------------------------------------------------------------
# The grid table (one row per error range) and summary.md.


_TIME_COLUMNS = ("time_mean_s", "time_min_s", "time_max_s")
# How failures ended and the contact metrics (TrialResult): failures ended early as settled,
# protective stops, the median peak sensed force (N), the share of the trials longer than 1.2 s
# whose chatter is under 5 N (%). grid.csv files from before them lack these columns.
_CONTACT_COLUMNS = ("settled", "protective_stops", "peak_force_median_n", "chatter_under_5n_pct")
GRID_COLUMNS = (
    "range",
    "linear_mm",
    "angular_deg",
    "quarter",
    "trials",
    "successes",
    "success_rate_pct",
    *_TIME_COLUMNS,
    *_CONTACT_COLUMNS,
)


@dataclasses.dataclass(frozen=True)
class GridTable:
    """Per-range results of an evaluation grid, R rows (NumPy arrays)."""

    linear_mm: np.ndarray  # (R,) +- linear error range (mm)
    angular_deg: np.ndarray  # (R,) +- angular error range (deg)
    trials: np.ndarray  # (R,) int
    successes: np.ndarray  # (R,) int
    time_mean_s: np.ndarray  # (R,) mean time to complete over successful trials (NaN if none)
    time_min_s: np.ndarray  # (R,)
    time_max_s: np.ndarray  # (R,)
    settled: np.ndarray | None = None  # (R,) int: failures ended early, settled
    protective_stops: np.ndarray | None = None  # (R,) int
    peak_force_median_n: np.ndarray | None = None  # (R,) median peak sensed force (N)
    chatter_under_5n_pct: np.ndarray | None = None  # (R,) % of trials > 1.2 s with chatter < 5 N

    @property
    def success_pct(self) -> np.ndarray:
        """(R,) success rate (%)."""
        return 100.0 * self.successes / np.maximum(self.trials, 1)

    @property
    def quarter(self) -> np.ndarray:
        return quarter_labels(self.linear_mm, self.angular_deg)

    def values(self, metric: str) -> np.ndarray:
        """(R,) per-range success rate (%) or mean time to complete (s)."""
        return self.success_pct if metric == "success" else self.time_mean_s

    def __len__(self) -> int:
        return int(self.trials.shape[0])

    def csv_text(self) -> str:
        """grid.csv: one row per range (mm, deg, %, s; 'nan' for no time)."""

        def fmt(value: float, digits: int = 4) -> str:
            return f"{value:.{digits}f}" if math.isfinite(value) else "nan"

        quarter, pct = self.quarter, self.success_pct
        nan = np.full(len(self), math.nan)
        contact = [nan if (v := getattr(self, c)) is None else v for c in _CONTACT_COLUMNS]
        digits = (0, 0, 2, 2)  # counts, N, %
        lines = [",".join(GRID_COLUMNS)]
        for i in range(len(self)):
            lines.append(
                f"{i},{self.linear_mm[i]:.6g},{self.angular_deg[i]:.6g},{quarter[i]},"
                f"{self.trials[i]},{self.successes[i]},{pct[i]:.2f},{fmt(self.time_mean_s[i])},"
                f"{fmt(self.time_min_s[i])},{fmt(self.time_max_s[i])},"
                + ",".join(fmt(float(c[i]), d) for c, d in zip(contact, digits, strict=True))
            )
        return "\n".join(lines) + "\n"

    @classmethod
    def from_csv(cls, path) -> GridTable:
        """The table in a grid.csv written by csv_text; ValueError (one line) if unreadable."""
        if not Path(path).exists():
            raise UsageError(f"{path} is missing: not a finished evaluation")
        text = inputs.read_text(path, MAX_GRID_CSV_BYTES)  # a regular file: a FIFO never blocks
        try:
            rows = list(csv.DictReader(io.StringIO(text, newline="")))
            if not rows:
                raise UsageError("no rows")
            col = {c: [r[c] for r in rows] for c in GRID_COLUMNS if c in rows[0]}
            contact = {c: np.array(col[c], dtype=float) for c in _CONTACT_COLUMNS if c in col}
            table = cls(
                **contact,
                **{c: np.array(col[c], dtype=float) for c in ("linear_mm", "angular_deg")},
                **{c: np.array(col[c], dtype=np.int64) for c in ("trials", "successes")},
                **{c: np.array(col[c], dtype=float) for c in _TIME_COLUMNS},
            )
            ranges = np.concatenate([table.linear_mm, table.angular_deg])
            if not (np.all(np.isfinite(ranges)) and np.all(ranges >= 0)):
                raise ValueError("an error range is not a number >= 0")
            if not (np.all(table.trials >= 1) and np.all(table.successes >= 0)):
                raise ValueError("a count of trials or successes is not a count")
            if np.any(table.successes > table.trials):
                raise ValueError("a range has more successes than trials")
            return table
        except (KeyError, TypeError, ValueError, OverflowError, csv.Error) as exc:
            shown = cli.message(exc)[:100]
            raise UsageError(f"{path} is not an evaluation grid.csv ({shown})") from None


_QUARTER_NAMES = {
    "Q1": "Q1 small lin. & ang.",
    "Q2": "Q2 small lin., large ang.",
    "Q3": "Q3 large lin., small ang.",
    "Q4": "Q4 large lin. & ang.",
}
_METRIC_TITLES = {
    "success": "Success rate per quarter (%)",
    "time": "Mean time to complete per quarter (s)",
}
_MIRROR = {"less": "greater", "greater": "less", "two-sided": "two-sided"}


def _num(value: float, digits: int) -> str:
    return "-" if not math.isfinite(value) else f"{value:.{digits}f}"


def _p(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{value:.3g}"


def _significant(value: bool | None) -> str:
    return "-" if value is None else ("significant" if value else "n.s.")


def _quarter_table(grid: GridTable, metric: str, paper: PaperCondition | None) -> list[str]:
    digits = 2
    ours = quarter_stats(grid.values(metric), grid.quarter)
    ref = None if paper is None else (paper.success if metric == "success" else paper.time)
    lines = [
        "| | " + " | ".join(_QUARTER_NAMES[q] for q in QUARTERS) + " |",
        "|---" * (len(QUARTERS) + 1) + "|",
        "| ranges | " + " | ".join(str(ours[q].n) for q in QUARTERS) + " |",
    ]
    for stat in ("mean", "min", "max"):
        cells = []
        for i, q in enumerate(QUARTERS):
            cell = _num(getattr(ours[q], stat), digits)
            if ref is not None:
                cell += f" ({getattr(ref, stat)[i]:g})"
            cells.append(cell)
        lines.append(f"| {stat} | " + " | ".join(cells) + " |")
    return lines


def _order_table(grid: GridTable, paper: PaperCondition | None) -> list[str]:
    lines = [
        "| quarters | metric | U | p (first better) | p (second better) | ours | paper |",
        "|---|---|---|---|---|---|---|",
    ]
    for metric in METRICS:
        order = None
        if paper is not None:
            order = paper.success_order if metric == "success" else paper.time_order
        for test in quarter_order_tests(grid.values(metric), grid.quarter, metric):
            found = test.conclusion()
            ours = "n.s." if found is None else f"{found[0]} better"
            if not math.isfinite(test.better.p):
                ours = "-"
            lines.append(
                f"| {test.first} vs {test.second} | {metric} | {_num(test.better.u, 1)} | "
                f"{_p(test.better.p)} | {_p(test.worse.p)} | {ours} | "
                f"{paper_order_conclusion(order, test.first, test.second)} |"
            )
    return lines


def _compare_table(
    grid: GridTable, other: GridTable, alternative: str, paper: PaperCondition | None
) -> list[str]:
    paper_col = None
    if paper is not None:
        paper_col = paper.after_vs_before if alternative == "greater" else paper.below_nominal
    lines = [
        "| quarter | metric | alternative | ranges (this / other) | mean this | mean other | U | p "
        "| ours | paper |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for metric in METRICS:
        alt = alternative if metric == "success" else _MIRROR[alternative]
        tests = compare_quarters(
            grid.values(metric), grid.quarter, other.values(metric), other.quarter, alt
        )
        ours_q = quarter_stats(grid.values(metric), grid.quarter)
        other_q = quarter_stats(other.values(metric), other.quarter)
        for i, q in enumerate(QUARTERS):
            t = tests[q]
            ours = "-" if not math.isfinite(t.p) else _significant(t.significant)
            ref = "-" if paper_col is None or metric != "success" else _significant(paper_col[i])
            lines.append(
                f"| {q} | {metric} | this {alt} | {t.n_x} / {t.n_y} | "
                f"{_num(ours_q[q].mean, 2)} | {_num(other_q[q].mean, 2)} | {_num(t.u, 1)} | "
                f"{_p(t.p)} | {ours} | {ref} |"
            )
    return lines


def summary_markdown(
    grid: GridTable,
    header: list[str],
    paper_name: str | None,
    other: GridTable | None = None,
    other_name: str = "",
    alternative: str = "less",
) -> str:
    """summary.md: per-quarter statistics beside the paper's, quarter-order and comparison tests.

    header: bullet lines describing the evaluation; paper_name: a key of PAPER or None; other:
    the grid of another evaluation to test against (one-sided per quarter, `alternative` for the
    success rate of this grid against the other's; the time uses the mirrored alternative).
    """
    paper = None if paper_name is None else PAPER[paper_name]
    lines = ["# Evaluation summary", ""] + [f"- {h}" for h in header] + [""]
    lines += [
        "Quarters split each error axis at its middle (the first half of the distinct ranges is "
        "small). Per range: success rate over all trials; mean time to complete over the "
        "successful trials (ranges without a success are left out of the time statistics).",
        "",
    ]
    for metric in METRICS:
        if paper is None:
            ref = "No paper condition matches this evaluation: no reference numbers."
        elif metric == "time" and paper.time is None:
            ref = f"The paper reports no times for {paper.title}."
        else:
            ref = f"In brackets: the paper's numbers, {paper.title} ({paper.grid})."
        lines += [f"## {_METRIC_TITLES[metric]}", "", ref, ""]
        lines += _quarter_table(grid, metric, paper) + [""]
    lines += [
        "## Quarter-order tests",
        "",
        f"One-sided Mann-Whitney U tests (scipy.stats.mannwhitneyu, alpha = {ALPHA}) between the "
        "per-range values of every pair of quarters, in both directions: 'better' is a "
        "significantly higher success rate or a significantly shorter mean time. U is the first "
        "quarter's statistic. The paper's column reads its 'Quarters' order' rows (Tables 4-5; "
        "a pair it does not list is n.s.).",
        "",
    ]
    lines += _order_table(grid, paper) + [""]
    if other is not None:
        lines += [
            f"## Against {other_name}",
            "",
            f"One-sided Mann-Whitney U tests per quarter (alpha = {ALPHA}) of this evaluation's "
            f"per-range values against {other_name}'s: success rate alternative '{alternative}', "
            f"time alternative '{_MIRROR[alternative]}'. The paper's column: "
            + (
                "its after-vs-before re-training tests (Table 4)."
                if alternative == "greater"
                else "its tests against nominal performance (Table 4 and section 6.3)."
            ),
            "",
        ]
        lines += _compare_table(grid, other, alternative, paper) + [""]
    return "\n".join(lines)
