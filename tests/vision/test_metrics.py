"""vision/metrics.py: yaw errors wrapped by the shape's symmetry, the percentiles of a report
worked out by hand, and the report's three files."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from mjx_peg.vision.metrics import REPORT_FILES, summarize, wrapped_yaw_error, write_report


@pytest.mark.parametrize(
    "shape, est_deg, true_deg, error_deg",
    [
        ("square", 89.0, 1.0, 2.0),  # a quarter turn apart is no error
        ("square", 46.0, 0.0, 44.0),
        ("triangle", 119.0, 0.0, 1.0),
        ("triangle", -61.0, 0.0, 59.0),
        ("square", 3.0, 363.0, 0.0),
    ],
)
def test_yaw_error_wraps_at_the_shapes_symmetry(shape, est_deg, true_deg, error_deg):
    error = wrapped_yaw_error(shape, math.radians(est_deg), math.radians(true_deg))
    assert math.degrees(error) == pytest.approx(error_deg, abs=1e-9)


def test_a_circle_has_no_yaw_error():
    assert math.isnan(wrapped_yaw_error("circle", 1.0, 0.0))


def _rows():
    """100 squares with position errors 1..100 mm (yaw 0.5 deg, the 10th's shape wrong) and 4
    circles at 2 mm (no yaw)."""
    rows = []
    for k in range(1, 101):
        rows.append(dict(image=f"{k:06d}.png", shape="square", pos_err_mm=float(k),
                         yaw_err_deg=0.5, shape_ok=k != 10, size_ok=True, floor_mm=0.5,
                         image_err_mm=float(k) - 0.5, latency_s=0.01 * k))  # fmt: skip
    for k in range(4):
        rows.append(dict(image=f"c{k}.png", shape="circle", pos_err_mm=2.0, yaw_err_deg=math.nan,
                         shape_ok=True, size_ok=k > 0, floor_mm=0.25, image_err_mm=1.75,
                         latency_s=0.02))  # fmt: skip
    return rows


def test_the_percentiles_by_hand():
    report = summarize(_rows())
    square, circle = report["per_shape"]["square"], report["per_shape"]["circle"]
    assert list(report["per_shape"]) == ["circle", "square"]  # in SHAPES order
    assert square["images"] == 100 and circle["images"] == 4
    assert (square["pos_p50_mm"], square["pos_p95_mm"], square["pos_p99_mm"]) == pytest.approx(
        (50.5, 95.05, 99.01)
    )  # linear interpolation between order statistics
    assert square["pos_max_mm"] == 100.0 and square["image_p50_mm"] == pytest.approx(50.0)
    assert square["yaw_p99_deg"] == 0.5 and circle["yaw_p50_deg"] is None
    assert square["shape_accuracy"] == 0.99 and circle["size_accuracy"] == 0.75
    assert square["within_paper_bar"] == 0.08  # 1..8 mm within 8 mm / 8 deg
    assert circle["within_paper_bar"] == 1.0  # no yaw: the position decides
    overall = report["overall"]
    assert overall["images"] == 104 and overall["yaw_max_deg"] == 0.5
    assert overall["floor_p99_mm"] == pytest.approx(0.5)
    assert report["latency_median_s"] == pytest.approx(np.median([r["latency_s"] for r in _rows()]))


def test_the_report_writes_its_three_files(tmp_path):
    report = write_report(_rows(), tmp_path / "eval", "a test split")
    assert sorted(p.name for p in (tmp_path / "eval").iterdir()) == sorted(REPORT_FILES)
    assert json.loads((tmp_path / "eval" / "metrics.json").read_text()) == json.loads(
        json.dumps(report)
    )
    errors = (tmp_path / "eval" / "errors.csv").read_text().splitlines()
    assert len(errors) == 105 and errors[0].startswith("image,shape,pos_err_mm")
    summary = (tmp_path / "eval" / "summary.md").read_text().splitlines()
    assert summary[0] == "# a test split"
    assert summary[4].startswith("| circle | 4 | 2.00 / 2.00 / 2.00 (2.00) | - / - / - (-) |")
    assert summary[5].startswith("| square | 100 | 50.50 / 95.05 / 99.01 (100.00) |")
    assert summary[6].startswith("| all | 104 |")
