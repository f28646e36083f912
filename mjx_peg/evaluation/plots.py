"""Heatmaps of an evaluation grid, annotated like the paper's Figs. 6-7, and its quarters beside
the paper's (Tables 4-5).

Rows are angular error ranges (increasing upwards), columns linear error ranges (increasing to
the right), so Q1 is bottom left and Q4 top right as in the paper. Every cell is annotated;
success rates above 95 % (times below 3 s) are boxed and bold, above 90 % (below 4 s) bold, as in
the paper's captions. Black lines mark the quarters.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402

from mjx_peg import outdir  # noqa: E402
from mjx_peg.evaluation.grid_table import GridTable  # noqa: E402
from mjx_peg.evaluation.paper_tables import PaperCondition  # noqa: E402
from mjx_peg.evaluation.stats import QUARTERS, quarter_stats  # noqa: E402

SUCCESS_BOX_PCT, SUCCESS_BOLD_PCT = 95.0, 90.0  # the paper's Fig. 6 thresholds
TIME_BOX_S, TIME_BOLD_S = 3.0, 4.0  # the paper's Fig. 7 thresholds
BOX_COLOR = "black"  # the paper boxes (cyan background) and bolds


def grid_matrix(grid: GridTable, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n_angular, n_linear) matrix of per-range values (NaN where absent) and the two axes."""
    linear, angular = np.unique(grid.linear_mm), np.unique(grid.angular_deg)
    matrix = np.full((angular.size, linear.size), np.nan)
    matrix[np.searchsorted(angular, grid.angular_deg), np.searchsorted(linear, grid.linear_mm)] = (
        values
    )
    return matrix, linear, angular


def heatmap(
    grid: GridTable,
    values: np.ndarray,
    path,
    title: str,
    label: str,
    fmt: str,
    boxed: Callable[[float], bool],
    bold: Callable[[float], bool],
    cmap: str,
    vmin: float | None = None,
    vmax: float | None = None,
) -> Path:
    """Write one annotated heatmap PNG (atomically) and return its path."""
    matrix, linear, angular = grid_matrix(grid, values)
    n_ang, n_lin = matrix.shape
    fig, ax = plt.subplots(figsize=(max(6.0, 0.62 * n_lin + 2.0), max(4.0, 0.42 * n_ang + 1.6)))
    colormap = plt.get_cmap(cmap).with_extremes(bad="#d0d0d0")  # grey: no value
    image = ax.imshow(
        np.ma.masked_invalid(matrix),
        origin="lower",
        aspect="auto",
        cmap=colormap,
        vmin=vmin,
        vmax=vmax,
        interpolation="nearest",
        alpha=0.75,  # light cells keep the annotations readable
    )
    fontsize = 8 if n_lin <= 12 else 6
    for i in range(n_ang):
        for j in range(n_lin):
            v = matrix[i, j]
            if not np.isfinite(v):
                ax.text(j, i, "-", ha="center", va="center", fontsize=fontsize)
                continue
            weight = "bold" if bold(v) or boxed(v) else "normal"
            ax.text(
                j, i, format(v, fmt), ha="center", va="center", fontsize=fontsize, fontweight=weight
            )
            if boxed(v):
                ax.add_patch(
                    Rectangle(
                        (j - 0.46, i - 0.42), 0.92, 0.84, fill=False, lw=1.6, edgecolor=BOX_COLOR
                    )
                )
    # Quarter lines between the small and large halves of each axis.
    ax.axvline(n_lin // 2 - 0.5, color="black", lw=2.0)
    ax.axhline(n_ang // 2 - 0.5, color="black", lw=2.0)
    ax.set_xticks(range(n_lin), [f"{v:.2f}" for v in linear], rotation=90, fontsize=fontsize + 1)
    ax.set_yticks(range(n_ang), [f"{v:.2f}" for v in angular], fontsize=fontsize + 1)
    ax.set_xlabel("linear error range, +- (mm)")
    ax.set_ylabel("angular error range, +- (deg)")
    ax.set_title(title, fontsize=10)
    fig.colorbar(image, ax=ax, label=label, fraction=0.04, pad=0.02)
    fig.tight_layout()
    return _save(fig, path)


def success_heatmap(grid: GridTable, path, title: str = "Success rate (%)") -> Path:
    """Per-range success rate (%); > 95 % boxed and bold, > 90 % bold."""
    return heatmap(
        grid,
        grid.success_pct,
        path,
        title,
        "success rate (%)",
        ".1f",
        boxed=lambda v: v > SUCCESS_BOX_PCT,
        bold=lambda v: v > SUCCESS_BOLD_PCT,
        cmap="RdYlGn",
        vmin=0.0,
        vmax=100.0,
    )


def time_heatmap(grid: GridTable, path, title: str = "Mean time to complete (s)") -> Path:
    """Per-range mean time to complete (s) over successes; < 3 s boxed and bold, < 4 s bold."""
    return heatmap(
        grid,
        grid.time_mean_s,
        path,
        title,
        "mean time to complete (s)",
        ".2f",
        boxed=lambda v: v < TIME_BOX_S,
        bold=lambda v: v < TIME_BOLD_S,
        cmap="RdYlGn_r",
    )


def paper_bars(grid: GridTable, paper: PaperCondition, path, title: str) -> Path:
    """Per-quarter mean (bar) and min-max (whiskers) of success rate and time, this evaluation
    beside the paper's numbers for the same condition (Tables 4-5); written atomically."""
    quarters = quarter_stats_by_metric(grid)
    metrics = [("success", "success rate (%)", paper.success)]
    if paper.time is not None:
        metrics.append(("time", "mean time to complete (s)", paper.time))
    fig, axes = plt.subplots(1, len(metrics), figsize=(4.6 * len(metrics), 3.8), squeeze=False)
    x = np.arange(len(QUARTERS))
    for ax, (metric, label, theirs) in zip(axes[0], metrics, strict=True):
        ours = quarters[metric]
        for offset, name, mean, low, high, color in (
            (-0.2, "ours", *ours, "tab:blue"),
            (0.2, "paper", theirs.mean, theirs.min, theirs.max, "tab:gray"),
        ):
            mean, low, high = (np.asarray(v, dtype=float) for v in (mean, low, high))
            ax.bar(x + offset, mean, 0.4, color=color, alpha=0.8, label=name)
            ax.errorbar(x + offset, mean, yerr=[mean - low, high - mean], fmt="none",
                        ecolor="black", capsize=3, lw=1)  # fmt: skip
        ax.set_xticks(x, QUARTERS)
        ax.set_ylabel(label)
        if metric == "success":
            ax.set_ylim(0.0, 100.0)
        ax.grid(axis="y", alpha=0.3)
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="lower center", ncol=2, fontsize=8)
    fig.suptitle(f"{title}\nbars: mean over ranges; whiskers: min-max", fontsize=9)
    fig.tight_layout(rect=(0.0, 0.06, 1.0, 1.0))
    return _save(fig, path)


def quarter_stats_by_metric(grid: GridTable) -> dict[str, tuple[list, list, list]]:
    """{"success"|"time": (means, mins, maxes)} over the ranges of each quarter, Q1..Q4."""
    out = {}
    for metric in ("success", "time"):
        stats = quarter_stats(grid.values(metric), grid.quarter)
        out[metric] = tuple(
            [getattr(stats[q], k) for q in QUARTERS] for k in ("mean", "min", "max")
        )
    return out


def _save(fig, path) -> Path:
    try:
        return outdir.write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=120))
    finally:
        plt.close(fig)
