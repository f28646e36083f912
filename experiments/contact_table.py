"""A markdown table of `experiments/contact.py --csv` runs of the same trials, paired.

    python experiments/contact_table.py --reference runs/contact/paper_nominal.csv \
        runs/contact/paper_*.csv

One row per CSV: success, protective stops, settled failures, the peak sensed force (median,
p99), the chatter's median and its share under 5 N (trials longer than 1.2 s), the time to
insert (p50), and against --reference (the same trials): trials lost and gained and the exact
McNemar p (two-sided binomial test on the trials whose outcome differs), and the difference in
success points.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np
from scipy.stats import binomtest

from mjx_peg.engines.trial import CHATTER_LIMIT_N, chatter_counted, smooth_pct


def load(path) -> dict[str, np.ndarray]:
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: np.asarray(data[name]) for name in data.dtype.names}


def paired(run: dict, reference: dict, name: str = "run") -> tuple[int, int, float, float]:
    """(lost, gained, McNemar p, change in success points) of `run` against `reference`, the
    same trials."""
    ok, ref = run["success"] > 0.5, reference["success"] > 0.5
    if ref.size != ok.size:
        raise SystemExit(f"{name}: {ok.size} trials, the reference has {ref.size}")
    lost, gained = int((ref & ~ok).sum()), int((~ref & ok).sum())
    p = binomtest(lost, lost + gained).pvalue if lost + gained else 1.0
    return lost, gained, p, 100 * (ok.mean() - ref.mean())


def row(name: str, run: dict, reference: dict | None) -> str:
    ok = run["success"] > 0.5
    n = ok.size
    peak = np.percentile(run["peak_force"], [50, 99])
    long = run["chatter"][chatter_counted(run["time_s"])]
    insert = np.median(run["time_s"][ok]) if ok.any() else float("nan")
    cells = [
        name,
        f"{100 * ok.mean():.1f} % ({int(ok.sum())} / {n})",
        f"{int(run['protective_stop'].sum())}",
        f"{int(run['settled'].sum())}",
        f"{peak[0]:.0f} / {peak[1]:.0f} N",
        f"{np.median(long):.2f} N, {smooth_pct(long):.1f} %",
        f"{insert:.1f} s",
    ]
    if reference is not None:
        lost, gained, p, change = paired(run, reference, name)
        cells.append(f"{change:+.1f} ({lost} lost, {gained} gained, p = {p:.2g})")
    return "| " + " | ".join(cells) + " |"


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("csv", nargs="+", type=pathlib.Path)
    p.add_argument("--reference", type=pathlib.Path, help="the run the others are paired with")
    args = p.parse_args(argv)
    reference = load(args.reference) if args.reference else None
    header = ["run", "success", "protective stops", "settled", "peak median / p99",
              f"chatter median, < {CHATTER_LIMIT_N:g} N", "insert p50"]  # fmt: skip
    if reference is not None:
        header.append(f"vs {args.reference.stem} (points)")
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for path in args.csv:
        print(row(path.stem, load(path), reference))


if __name__ == "__main__":
    main()
