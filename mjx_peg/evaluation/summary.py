"""summary.md of an evaluation: its quarters beside the paper's, quarter-order and comparison tests.

Per metric (success rate %, mean time to complete s) a table of each quarter's mean, min and max
over its ranges, the paper's numbers in brackets (Tables 4-5); the quarter-order tests (every pair
of quarters, both one-sided directions, `stats.quarter_order_tests`) beside the paper's
"Quarters' order" rows; and, given another evaluation, one-sided tests per quarter against it
(`stats.compare_quarters`) beside the paper's tests against nominal or before transfer.
"""

from __future__ import annotations

import math

from mjx_peg.evaluation.grid_table import GridTable
from mjx_peg.evaluation.paper_tables import PAPER, PaperCondition, paper_order_conclusion
from mjx_peg.evaluation.stats import (
    ALPHA,
    METRICS,
    QUARTERS,
    compare_quarters,
    quarter_order_tests,
    quarter_stats,
)

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
