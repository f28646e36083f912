"""evaluation/paper_tables.py: the paper's Tables 4-5 as transcribed, against the paper's text."""

import re
from pathlib import Path

import pytest

from mjx_peg.evaluation.paper_tables import PAPER, paper_condition_for, paper_order_conclusion

REPO = Path(__file__).resolve().parents[2]
PAPER_TEX = REPO.parent / "shared" / "paper" / "spector-zacksenhouse-compliant-dmp.tex"


def _tex_rows(text: str, label: str) -> list[list[float]]:
    rows = re.findall(r"\\textbf\{" + label + r"\}\s*((?:&\s*[0-9.]+\s*){4})", text)
    return [[float(v) for v in re.findall(r"[0-9.]+", r)] for r in rows]


def test_paper_numbers_match_tables_4_and_5():
    nominal = PAPER["nominal"]
    assert nominal.success.mean == (96.96, 94.22, 91.83, 87.83)
    assert nominal.time.mean == (1.9, 2.72, 4.34, 4.88)
    assert nominal.success_order == {
        ("Q1", "Q2"),
        ("Q1", "Q3"),
        ("Q1", "Q4"),
        ("Q2", "Q3"),
        ("Q2", "Q4"),
        ("Q3", "Q4"),
    }
    assert paper_order_conclusion(PAPER["25mm"].success_order, "Q2", "Q3") == "Q3 better"
    assert paper_order_conclusion(PAPER["25mm"].success_order, "Q1", "Q3") == "n.s."
    if not PAPER_TEX.is_file():
        pytest.skip(f"{PAPER_TEX} not available")
    text = PAPER_TEX.read_text()
    split = text.index(r"\label{tab:summary results time}")
    success_conditions = ["nominal", "60mm", "25mm", "triangle", "transfer"]
    time_conditions = ["nominal", "60mm", "25mm", "transfer"]
    for part, conditions, metric in (
        (text[:split], success_conditions, "success"),
        (text[split:], time_conditions, "time"),
    ):
        for stat in ("mean", "min", "max"):
            rows = _tex_rows(part, stat)
            assert len(rows) == len(conditions), (metric, stat, rows)
            for name, row in zip(conditions, rows, strict=True):
                ours = getattr(getattr(PAPER[name], metric), stat)
                assert list(ours) == row, (name, metric, stat)


def test_an_evaluation_finds_the_paper_condition_of_its_shapes_and_size():
    assert paper_condition_for(("circle", "square"), 50.0) == "nominal"
    assert paper_condition_for(("square",), 60.0) == "60mm"
    assert paper_condition_for(("circle",), 25.0) == "25mm"
    assert paper_condition_for(("triangle",), 50.0) == "triangle"
    assert paper_condition_for(("triangle",), 25.0) is None  # the paper has no such condition
    assert paper_condition_for(("circle", "triangle"), 50.0) is None
    assert paper_order_conclusion(None, "Q1", "Q2") == "-"
