"""How well a localizer does on a rendered split: error percentiles per shape, class accuracy.

    python -m mjx_peg.vision evaluate --model runs/vision/model --data runs/vision/data/test \
        --out runs/vision/eval/test

Per image: position error (mm, the estimated hole centre to the true one on the table), yaw
error (deg, wrapped to +- half the true shape's symmetry period; circles have none), shape and
size right or wrong, and the *calibration floor*: where the true hole would be found by a
perfect detector that reads the exact pixel and back-projects it through the (slightly wrong)
calibration, the part of the error no image model can remove; the *image-only* error is the
estimate's distance from that point. Writes errors.csv (one row per
image), metrics.json and summary.md into --out.
"""

from __future__ import annotations

import csv
import json
import math
import os
import time
from pathlib import Path

import numpy as np

from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.vision.dataset import read_png, split_config, split_items, yaw_period
from mjx_peg.vision.localizer import Localizer
from mjx_peg.world import constants
from mjx_peg.world.constants import SHAPES

PERCENTILES = (50, 95, 99)
REPORT_FILES = ("errors.csv", "metrics.json", "summary.md")
PAPER_BAR = (8.0, 8.0)  # mm, deg: the paper's YOLO-like model's maximum error
GOAL = (2.0, 2.0)  # mm, deg at the 99th percentile


def wrapped_yaw_error(shape: str, est: float, true: float) -> float:
    """|est - true| (rad) modulo the shape's symmetry period; NaN for circles."""
    period = yaw_period(shape)
    if math.isinf(period):
        return math.nan
    return abs(float(np.mod(est - true + period / 2, period) - period / 2))


def evaluate_items(localizer: Localizer, items, progress: bool = True) -> list[dict]:
    """One row per (png, label): errors, classes, the calibration floor and the latency."""
    from tqdm import tqdm

    rows = []
    for png, label in tqdm(
        items, desc="localizing", unit="img", disable=not progress, dynamic_ncols=True
    ):
        image = read_png(png)
        calib = CameraCalibration.from_json(label["calibration"])
        t0 = time.perf_counter()
        result = localizer.localize(image, calib)
        latency = time.perf_counter() - t0
        b, e = label["board"], result.estimate
        floor = calib.unproject_to_plane(np.asarray(label["hole_px"]), constants.HOLE_DEPTH)
        rows.append(
            {
                "image": Path(png).name,
                "shape": b["shape"],
                "size_mm": round(b["size"] * 1000, 3),
                "pos_err_mm": 1000 * math.hypot(e.x - b["x"], e.y - b["y"]),
                "yaw_err_deg": math.degrees(wrapped_yaw_error(b["shape"], e.yaw, b["yaw"])),
                "shape_ok": e.shape == b["shape"],
                "size_ok": abs(e.size - b["size"]) < 1e-6,
                "floor_mm": 1000 * math.hypot(floor[0] - b["x"], floor[1] - b["y"]),
                "image_err_mm": 1000 * math.hypot(e.x - floor[0], e.y - floor[1]),
                "coarse_err_mm": 1000
                * math.hypot(result.coarse_xy[0] - b["x"], result.coarse_xy[1] - b["y"]),
                "latency_s": latency,
                "true_x": b["x"],
                "true_y": b["y"],
                "true_yaw_deg": math.degrees(b["yaw"]),
                "est_x": e.x,
                "est_y": e.y,
                "est_yaw_deg": math.degrees(e.yaw),
                "est_shape": e.shape,
                "est_size_mm": 1000 * e.size,
            }
        )
    return rows


def _stats(rows: list[dict]) -> dict:
    pos = np.array([r["pos_err_mm"] for r in rows])
    yaw = np.array([r["yaw_err_deg"] for r in rows])
    yaw = yaw[np.isfinite(yaw)]
    floor = np.array([r["floor_mm"] for r in rows])
    out = {"images": len(rows)}
    for p in PERCENTILES:
        out[f"pos_p{p}_mm"] = float(np.percentile(pos, p))
    out["pos_max_mm"] = float(pos.max())
    for p in PERCENTILES:
        out[f"yaw_p{p}_deg"] = float(np.percentile(yaw, p)) if yaw.size else None
    out["yaw_max_deg"] = float(yaw.max()) if yaw.size else None
    out["shape_accuracy"] = float(np.mean([r["shape_ok"] for r in rows]))
    out["size_accuracy"] = float(np.mean([r["size_ok"] for r in rows]))
    out["floor_p99_mm"] = float(np.percentile(floor, 99))
    image = np.array([r["image_err_mm"] for r in rows])
    for p in PERCENTILES:
        out[f"image_p{p}_mm"] = float(np.percentile(image, p))
    out["within_paper_bar"] = float(
        np.mean(
            [
                r["pos_err_mm"] <= PAPER_BAR[0] and not (r["yaw_err_deg"] > PAPER_BAR[1])
                for r in rows
            ]
        )
    )
    return out


def summarize(rows: list[dict]) -> dict:
    """{'overall': stats, 'per_shape': {shape: stats}, 'latency_s': median}."""
    per_shape = {
        s: _stats([r for r in rows if r["shape"] == s])
        for s in SHAPES
        if any(r["shape"] == s for r in rows)
    }
    return {
        "overall": _stats(rows),
        "per_shape": per_shape,
        "latency_median_s": float(np.median([r["latency_s"] for r in rows])),
        "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "unset"),
    }


def evaluate_split(localizer: Localizer, split_dir, progress: bool = True) -> dict:
    """`summarize` of a localizer on every image of a split."""
    return summarize(evaluate_items(localizer, split_items(split_dir), progress))


def _fmt(v, digits=2) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def summary_markdown(report: dict, title: str) -> str:
    """A table per shape: p50/p95/p99 position and yaw error, accuracies, the calibration floor."""
    lines = [
        f"# {title}",
        "",
        "| shape | images | position p50 / p95 / p99 (max) mm | yaw p50 / p95 / p99 (max) deg "
        "| shape acc. | size acc. | within 8 mm / 8 deg | calibration floor p99 mm "
        "| image-only position p50 / p95 / p99 mm |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    groups = [*report["per_shape"].items(), ("all", report["overall"])]
    for name, s in groups:
        pos = " / ".join(_fmt(s[f"pos_p{p}_mm"]) for p in PERCENTILES)
        yaw = " / ".join(_fmt(s[f"yaw_p{p}_deg"]) for p in PERCENTILES)
        lines.append(
            f"| {name} | {s['images']} | {pos} ({_fmt(s['pos_max_mm'])}) | {yaw} "
            f"({_fmt(s['yaw_max_deg'])}) | {100 * s['shape_accuracy']:.1f} % | "
            f"{100 * s['size_accuracy']:.1f} % | {100 * s['within_paper_bar']:.1f} % | "
            f"{_fmt(s['floor_p99_mm'])} | "
            + " / ".join(_fmt(s[f"image_p{p}_mm"]) for p in PERCENTILES)
            + " |"
        )
    lines += [
        "",
        f"Paper's bar: {PAPER_BAR[0]:g} mm / {PAPER_BAR[1]:g} deg; goal {GOAL[0]:g} mm / "
        f"{GOAL[1]:g} deg at p99. Circles have no yaw. Median latency per image "
        f"{1000 * report['latency_median_s']:.0f} ms (NumPy, OPENBLAS_NUM_THREADS="
        f"{report.get('blas_threads', 'unset')}, image already decoded).",
        "",
        "Calibration floor: the error of a perfect image model that finds the hole's exact pixel "
        "and back-projects it through the stated calibration (the true camera is off it within "
        "the calibration error). Image-only: the estimate against that point, i.e. the "
        "localizer's own error with the calibration's taken out.",
    ]
    return "\n".join(lines) + "\n"


def write_report(rows: list[dict], out_dir, title: str) -> dict:
    """errors.csv, metrics.json and summary.md in out_dir (each written atomically)."""
    import io

    from mjx_peg import outdir

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    table = io.StringIO()
    writer = csv.DictWriter(table, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    outdir.write_atomic(out / "errors.csv", table.getvalue())
    report = summarize(rows)
    outdir.write_atomic(out / "metrics.json", json.dumps(report, indent=2) + "\n")
    outdir.write_atomic(out / "summary.md", summary_markdown(report, title))
    return report


def evaluate_to(localizer: Localizer, split_dir, out_dir, progress: bool = True) -> dict:
    """Evaluate on a split and write the report (the title names the split's condition)."""
    config = split_config(split_dir)
    rows = evaluate_items(localizer, split_items(split_dir), progress)
    title = (
        f"Localizer on {Path(split_dir)} ({len(rows)} renders, seed {config.seed}, "
        f"condition {config.condition}, {config.width}x{config.height})"
    )
    return write_report(rows, out_dir, title)
