"""Paired check of early ending: the same grid run with and without it, trial by trial.

    python eval.py --policy baseline --grid paper-small --out runs/eval/early
    python eval.py --policy baseline --grid paper-small --full-time-limit --out runs/eval/full
    python experiments/early_ending.py runs/eval/early runs/eval/full [--write [FILE]]

Both evaluations must hold the same grid, trials and seed (so trial k of range r is the same
board, grasp and friction in both); only `--full-time-limit` may differ. Prints the fraction of
trials with the same outcome, every trial that differs (range, index, errors, both outcomes and
times), the simulated steps each run needed and what early ending saved. `--write` replaces the
"## Early ending" section of BENCHMARKS.md (or of FILE).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from mjx_peg.evaluation import eval_dir

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _report import ROOT, write_section  # noqa: E402  (benchmarks/_report.py)


def compare(early_dir: Path, full_dir: Path) -> tuple[list[str], float]:
    early_cfg, _ = eval_dir.read_eval_dir(early_dir)
    full_cfg, _ = eval_dir.read_eval_dir(full_dir)
    a, b = early_cfg.to_json(), full_cfg.to_json()
    a.pop("full_time_limit"), b.pop("full_time_limit")
    if a != b:
        diff = sorted(k for k in a if a[k] != b.get(k))
        sys.exit(f"early_ending.py: error: the two evaluations differ in {', '.join(diff)}")
    if early_cfg.full_time_limit or not full_cfg.full_time_limit:
        sys.exit("early_ending.py: error: give the early-ending evaluation first, the full second")

    ranges = early_cfg.ranges
    same = total = settled = steps_early = steps_full = won_early = won_full = 0
    rows = []
    for i, (lin, ang) in enumerate(ranges):
        e, f = (
            eval_dir.load_range(early_dir, early_cfg, i),
            eval_dir.load_range(full_dir, full_cfg, i),
        )
        if e is None or f is None:
            sys.exit(f"early_ending.py: error: range {i} has not finished in both evaluations")
        total += e["success"].size
        same += int((e["success"] == f["success"]).sum())
        won_early += int(e["success"].sum())
        won_full += int(f["success"].sum())
        settled += int(e["settled"].sum())
        steps_early += int(e["steps"].sum())
        steps_full += int(f["steps"].sum())
        for k in np.flatnonzero(e["success"] != f["success"]):
            rows.append(
                f"| {i} | {k} | {lin:g} mm / {ang:g} deg | "
                f"{'success' if e['success'][k] else 'failure'}"
                f"{' (settled)' if e['settled'][k] else ''} at {e['time_s'][k]:.2f} s | "
                f"{'success' if f['success'][k] else 'failure'} at {f['time_s'][k]:.2f} s |"
            )
    share = same / total
    lines = [
        f"Grid `{early_cfg.grid}`, policy `{early_cfg.policy[:19]}`, {total:,} trials "
        f"({len(ranges)} ranges x {early_cfg.trials}), {early_cfg.time_limit_s:g} s limit, seed "
        f"{early_cfg.seed}; the same trials run with early ending (`{early_dir}`) and with every "
        f"failure to the limit (`{full_dir}`, `--full-time-limit`).",
        "",
        "| | with early ending | every failure to the limit |",
        "|---|---:|---:|",
        f"| success | {100 * won_early / total:.2f} % | {100 * won_full / total:.2f} % |",
        f"| physics steps | {steps_early / 1e6:.1f} M | {steps_full / 1e6:.1f} M |",
        f"| trials ended early (settled) | {settled:,} | 0 |",
    ]
    lines += [
        "",
        f"Same outcome: {same:,} of {total:,} trials ({100 * share:.2f} %); early ending "
        f"simulated {100 * steps_early / steps_full:.1f} % of the steps.",
    ]
    if rows:
        lines += [
            "",
            "Every trial whose outcome differs:",
            "",
            "| range | trial | errors | with early ending | to the limit |",
            "|---:|---:|---|---|---|",
            *rows,
        ]
    return lines, share


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("early", type=Path, help="evaluation with early ending (the default)")
    p.add_argument("full", type=Path, help="the same evaluation with --full-time-limit")
    p.add_argument("--write", nargs="?", type=Path, const=ROOT / "BENCHMARKS.md", metavar="FILE",
                   help="update the section in FILE (default BENCHMARKS.md)")  # fmt: skip
    args = p.parse_args(argv)
    lines, _ = compare(args.early, args.full)
    print("\n".join(lines))
    if args.write:
        cmd = f"python experiments/early_ending.py {args.early} {args.full} --write"
        section = "\n".join(["## Early ending", "", *lines, "", f"Reproduce: `{cmd}`", ""])
        write_section(args.write, "## Early ending", section)


if __name__ == "__main__":
    main()
