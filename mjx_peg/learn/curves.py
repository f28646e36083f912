"""The learning curve, drawn like the paper's Fig. 5: return per trial and its running mean."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from mjx_peg.world.constants import SUCCESS_REWARD

RUNNING_MEAN = 100  # trials, as in the paper's figure


def read_table(path) -> dict[str, list[float]]:
    """A CSV written by RunDir as {column: [float, ...]} (empty cells -> nan)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    return {
        name: [float(r[i]) if r[i] != "" else float("nan") for r in rows[1:]]
        for i, name in enumerate(header)
    }


def running_mean(x: np.ndarray, window: int) -> np.ndarray:
    """Mean of the last `window` values at every index (fewer at the start)."""
    c = np.cumsum(np.insert(np.asarray(x, np.float64), 0, 0.0))
    i = np.arange(1, len(x) + 1)
    lo = np.maximum(i - window, 0)
    return (c[i] - c[lo]) / (i - lo)


def plot_training_curve(trials_csv, out_png, title: str = "") -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = read_table(trials_csv)
    trial = np.asarray(table["trial"]) + 1
    ret = np.asarray(table["return"])
    fig, ax = plt.subplots(figsize=(8, 4.5), dpi=120)
    ax.plot(trial, ret, color="tab:red", alpha=0.15, lw=0.6, label="return per trial")
    full = min(RUNNING_MEAN, len(ret)) - 1  # draw the mean once its window is full
    ax.plot(
        trial[full:],
        running_mean(ret, RUNNING_MEAN)[full:],
        color="tab:red",
        lw=2.2,
        label=f"running mean ({RUNNING_MEAN} trials)",
    )
    ax.axhline(SUCCESS_REWARD, color="0.5", ls=":", lw=1, label="success reward (38000)")
    ax.set_xlabel("trials")
    ax.set_ylabel("return (paper scale)")
    ax.set_ylim(-1000, SUCCESS_REWARD * 1.05)
    ax.set_title(title or "Training curve")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    fig.tight_layout()
    out_png = Path(out_png)
    fig.savefig(out_png)
    plt.close(fig)
    return out_png
