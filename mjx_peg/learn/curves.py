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


# The paper's training curve (section 6.1, Fig. 5): slow over the first ~6,000 trials, fast
# over the next ~2,000, the mean return above 92 % of the maximum after ~8,000
PAPER_TRIALS_TO_92 = 8000
PAPER_FRACTION = 0.92


def _table_or_none(path):
    """read_table of `path`, or None where it is absent or holds no row."""
    if path is None or not Path(path).is_file():
        return None
    table = read_table(path)
    return table if table and len(next(iter(table.values()))) else None


def plot_training_curve(trials_csv, out_png, title: str = "", metrics_csv=None,
                        eval_csv=None) -> Path:  # fmt: skip
    """The run's return per trial and its running mean (the paper's Fig. 5), with the paper's
    92 % of the maximum after ~8,000 trials marked; below it, where metrics_csv / eval_csv are
    given, the success rate per iteration of the exploring policy and of its mean on the held-out
    trials (`monitor.HeldOut`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = read_table(trials_csv)
    metrics, held = _table_or_none(metrics_csv), _table_or_none(eval_csv)
    panels = 2 if metrics is not None or held is not None else 1
    fig, axes = plt.subplots(panels, 1, figsize=(8, 4.5 + 2.5 * (panels - 1)), dpi=120,
                             sharex=True, squeeze=False)  # fmt: skip
    ax = axes[0, 0]
    trial = np.asarray(table["trial"]) + 1
    ret = np.asarray(table["return"])
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
    ax.plot([PAPER_TRIALS_TO_92], [PAPER_FRACTION * SUCCESS_REWARD], "k*", ms=9,
            label="the paper: 92 % of the maximum after ~8,000 trials")  # fmt: skip
    ax.set_ylabel("return (paper scale)")
    ax.set_ylim(-1000, SUCCESS_REWARD * 1.05)
    ax.set_title(title or "Training curve")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    if panels == 2:
        ax = axes[1, 0]
        if metrics is not None:
            ax.plot(metrics["trials"], 100 * np.asarray(metrics["success_rate"]), "o-",
                    color="tab:red", ms=3, label="exploring policy (per iteration)")  # fmt: skip
        if held is not None:
            ax.plot(held["trials"], 100 * np.asarray(held["success_rate"]), "s-",
                    color="tab:blue", ms=4, label="its mean, held-out trials")  # fmt: skip
        ax.set_ylabel("success (%)")
        ax.set_ylim(0, 101)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=8)
    axes[-1, 0].set_xlabel("trials")
    fig.tight_layout()
    out_png = Path(out_png)
    fig.savefig(out_png)
    plt.close(fig)
    return out_png
