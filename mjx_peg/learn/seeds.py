"""A set of training runs over seeds (`train.py --seeds 0,1,2 --out BASE`): their curves and spread.

    python -m mjx_peg.learn.seeds BASE      # writes BASE/seeds.csv and BASE/seeds.png

Each seed's run lies in BASE/seed-N (a run directory of its own). The runs of one set share
their config but the seed, so their iterations end at the same trial counts: per iteration the
table gives, over the seeds, the mean, the standard deviation, the least and the largest of the
running mean return (100 trials, the paper's curve), the exploring policy's success and, where
the runs evaluate their mean on held-out trials (`--eval-every`), its success; the figure draws
each mean with its min-max band and every seed's curve, the paper's 92 % after ~8,000 trials
marked. The line it prints is the set's final numbers.
"""

from __future__ import annotations

import argparse
import csv
import io
import re
import sys
from pathlib import Path

import numpy as np

from mjx_peg.errors import UsageError
from mjx_peg.learn.curves import (
    PAPER_FRACTION,
    PAPER_TRIALS_TO_92,
    RUNNING_MEAN,
    read_table,
    running_mean,
)
from mjx_peg.world.constants import SUCCESS_REWARD

SEED_DIR = re.compile(r"^seed-(\d+)$")
CURVES = ("return_running_mean", "success_rate", "eval_success_rate")


def seed_runs(base) -> dict[int, Path]:
    """{seed: run directory} of BASE/seed-N folders that hold a metrics.csv, by seed."""
    base = Path(base)
    if not base.is_dir():
        raise UsageError(f"{base} is not a directory")
    runs = {}
    for child in base.iterdir():
        match = SEED_DIR.match(child.name)
        if match and (child / "metrics.csv").is_file():
            runs[int(match.group(1))] = child
    if not runs:
        raise UsageError(f"{base} holds no seed-N run directory with a metrics.csv")
    return dict(sorted(runs.items()))


def seed_curves(run: Path) -> dict[str, dict[int, float]]:
    """One run's curves, each {trials seen at an iteration's end: value}."""
    metrics = read_table(run / "metrics.csv")
    ends = [int(t) for t in metrics["trials"]]
    curves: dict[str, dict[int, float]] = {
        "success_rate": dict(zip(ends, metrics["success_rate"], strict=True)),
        "return_running_mean": {},
        "eval_success_rate": {},
    }
    if (run / "trials.csv").is_file():
        mean = running_mean(np.asarray(read_table(run / "trials.csv")["return"]), RUNNING_MEAN)
        curves["return_running_mean"] = {t: float(mean[t - 1]) for t in ends if t <= mean.size}
    if (run / "eval.csv").is_file():
        held = read_table(run / "eval.csv")
        curves["eval_success_rate"] = dict(
            zip((int(t) for t in held["trials"]), held["success_rate"], strict=True)
        )
    return curves


def aggregate(base) -> tuple[dict[int, Path], list[dict]]:
    """The runs, and one row per trial count that any run reached: per curve the mean, std,
    min, max over the seeds that have it, and how many do."""
    runs = seed_runs(base)
    curves = {seed: seed_curves(run) for seed, run in runs.items()}
    ends = sorted({t for c in curves.values() for curve in c.values() for t in curve})
    rows = []
    for t in ends:
        row = {"trials": t}
        for name in CURVES:
            values = np.array([c[name][t] for c in curves.values() if t in c[name]])
            values = values[np.isfinite(values)]
            row[f"{name}_seeds"] = values.size
            for stat, f in (("mean", np.mean), ("std", np.std), ("min", np.min), ("max", np.max)):
                row[f"{name}_{stat}"] = float(f(values)) if values.size else float("nan")
        rows.append(row)
    return runs, rows


def _write_table(rows: list[dict], path: Path) -> None:
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, fieldnames=list(rows[0]))
    writer.writeheader()
    for row in rows:
        writer.writerow({k: f"{v:.6g}" if isinstance(v, float) else v for k, v in row.items()})
    path.write_text(text.getvalue())


def plot_seeds(base, runs: dict[int, Path], rows: list[dict], out_png) -> Path:
    """seeds.png: the running mean return and the success rates, mean and min-max band over the
    seeds, each seed's curve thin."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(8, 7), dpi=120, sharex=True)
    trials = np.array([r["trials"] for r in rows])
    per_seed = {seed: seed_curves(run) for seed, run in runs.items()}
    for ax, names, scale in (
        (axes[0], ("return_running_mean",), 1.0),
        (axes[1], ("success_rate", "eval_success_rate"), 100.0),
    ):
        for name, color in zip(names, ("tab:red", "tab:blue"), strict=False):
            have = np.array([r[f"{name}_seeds"] > 0 for r in rows])
            if not have.any():
                continue
            t = trials[have]
            mean = scale * np.array([r[f"{name}_mean"] for r in rows])[have]
            lo = scale * np.array([r[f"{name}_min"] for r in rows])[have]
            hi = scale * np.array([r[f"{name}_max"] for r in rows])[have]
            label = {
                "return_running_mean": f"running mean return ({RUNNING_MEAN} trials)",
                "success_rate": "exploring policy, per iteration",
                "eval_success_rate": "its mean on held-out trials",
            }[name]
            ax.fill_between(t, lo, hi, color=color, alpha=0.2, lw=0)
            ax.plot(t, mean, color=color, lw=2, label=f"{label}: mean of {len(runs)} seeds")
            for curve in per_seed.values():
                xs = sorted(curve[name])
                ax.plot(xs, [scale * curve[name][x] for x in xs], color=color, lw=0.6, alpha=0.5)
    axes[0].axhline(SUCCESS_REWARD, color="0.5", ls=":", lw=1)
    axes[0].plot([PAPER_TRIALS_TO_92], [PAPER_FRACTION * SUCCESS_REWARD], "k*", ms=9,
                 label="the paper: 92 % of the maximum after ~8,000 trials")  # fmt: skip
    axes[0].set_ylabel("return (paper scale)")
    axes[0].set_ylim(-1000, SUCCESS_REWARD * 1.05)
    axes[1].set_ylabel("success (%)")
    axes[1].set_ylim(0, 101)
    axes[1].set_xlabel("trials")
    axes[0].set_title(f"{Path(base).name}: seeds {', '.join(str(s) for s in runs)}")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    out_png = Path(out_png)
    fig.savefig(out_png)
    plt.close(fig)
    return out_png


def summarize(base) -> str:
    """Write BASE/seeds.csv and BASE/seeds.png; the set's final numbers as one line."""
    base = Path(base)
    runs, rows = aggregate(base)
    _write_table(rows, base / "seeds.csv")
    plot_seeds(base, runs, rows, base / "seeds.png")
    last = rows[-1]
    parts = [f"{len(runs)} seeds ({', '.join(str(s) for s in runs)}), {last['trials']:,} trials"]
    for name, label, scale, unit in (
        ("return_running_mean", "running mean return", 1.0, ""),
        ("success_rate", "exploring success", 100.0, " %"),
        ("eval_success_rate", "held-out success of the mean", 100.0, " %"),
    ):
        if last[f"{name}_seeds"]:
            parts.append(
                f"{label} {scale * last[f'{name}_mean']:.1f}{unit} (std "
                f"{scale * last[f'{name}_std']:.1f}, {scale * last[f'{name}_min']:.1f}-"
                f"{scale * last[f'{name}_max']:.1f})"
            )
    return "; ".join(parts) + f"; {base / 'seeds.png'}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m mjx_peg.learn.seeds",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("base", type=Path, help="the --out of train.py --seeds")
    args = parser.parse_args(argv)
    try:
        print(summarize(args.base))
    except UsageError as e:
        print(f"{parser.prog}: error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())


__all__ = ["aggregate", "plot_seeds", "seed_curves", "seed_runs", "summarize"]
