"""The paper's reference numbers: Tables 4 and 5 and the tests stated in sections 6.2-6.5.

Transcribed from paper/spector-zacksenhouse-compliant-dmp.tex: Table 4 (tab:summary results,
success rate %) and Table 5 (tab:summary results time, s), mean, min and max over the ranges of
each quarter, their "Quarters' order" rows, and the tests stated only in the text of sections
6.3-6.5 (60 / 25 mm and the triangle against nominal, the triangle after transfer against
before). Each condition is one `PaperCondition`; `paper_condition_for` finds the one an
evaluation matches by its shapes and size.
"""

from __future__ import annotations

import dataclasses
import math


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
