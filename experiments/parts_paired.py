"""Two columns of the parts suite paired trial for trial: a markdown table.

    python experiments/parts_paired.py RUN REFERENCE [--trials FIRST:END] [--only PART,...]

RUN and REFERENCE are folders of per-part CSVs that `experiments/parts_suite.py` wrote (OUT/LABEL,
e.g. docs/results/parts/baseline), the same trials of each part (the suite's seed and trials).
One row per part both hold: the reference's success and the run's, the trials lost and gained
and the exact McNemar p (`evaluation.stats.mcnemar_p`), the protective stops of each and the
median time to insert of each over the trials both inserted; then every part together.
`--trials 100:300` pairs only those trials of each part (e.g. the ones a screen of `--first 100`
did not see); a part with fewer rows in either folder pairs the rows both hold.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from mjx_peg.evaluation.stats import mcnemar_p


def read_part(path: Path) -> dict[str, np.ndarray]:
    """A part's CSV as arrays: success, protective_stop (bool), time_s (float)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    try:
        return {
            "success": np.array([r["success"] == "1" for r in rows], dtype=bool),
            "protective_stop": np.array([r["protective_stop"] == "1" for r in rows], dtype=bool),
            "time_s": np.array([float(r["time_s"]) for r in rows]),
        }
    except (KeyError, ValueError) as e:
        raise SystemExit(f"{path}: not a parts-suite CSV ({e})") from None


def paired_rows(run: Path, reference: Path, first: int, end: int | None, only=None) -> list:
    """[(part, reference arrays, run arrays)] of the parts both hold, trials [first, end)."""
    rows = []
    for path in sorted(reference.glob("*.csv")):
        part = path.stem
        if (only and part not in only) or not (run / path.name).is_file():
            continue
        ref, new = read_part(path), read_part(run / path.name)
        n = min(len(ref["success"]), len(new["success"]), end or len(ref["success"]))
        if n <= first:
            continue
        rows.append((part, *({k: v[first:n] for k, v in d.items()} for d in (ref, new))))
    return rows


def _median_time(ref: dict, new: dict) -> str:
    both = ref["success"] & new["success"]
    if not both.any():
        return "-"
    return f"{np.median(ref['time_s'][both]):.2f} → {np.median(new['time_s'][both]):.2f} s"


def table(rows: list) -> str:
    """The markdown table of `paired_rows`, a row per part and one for all of them."""
    lines = [
        "| part | trials | reference | run | lost / gained, McNemar p | protective stops | "
        "median time to insert (both inserted) |",
        "|---|---:|---:|---:|---|---|---|",
    ]

    def line(name, ref, new):
        a, b = ref["success"], new["success"]
        lost, gained = int(np.sum(a & ~b)), int(np.sum(~a & b))
        stops = f"{int(ref['protective_stop'].sum())} → {int(new['protective_stop'].sum())}"
        return (f"| {name} | {len(a)} | {100 * a.mean():.1f} % | {100 * b.mean():.1f} % | "
                f"{lost} / {gained}, p = {mcnemar_p(a, b):.2g} | {stops} | "
                f"{_median_time(ref, new)} |")  # fmt: skip

    for part, ref, new in rows:
        lines.append(line(part, ref, new))
    if len(rows) > 1:
        every = [{k: np.concatenate([r[i][k] for r in rows]) for k in rows[0][1]} for i in (1, 2)]
        lines.append(line(f"**all {len(rows)}**", *every))
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("run", type=Path, help="a folder of the suite's per-part CSVs")
    p.add_argument("reference", type=Path, help="the folder it is paired with")
    p.add_argument("--trials", default="0:", help="FIRST:END of each part's trials (default all)")
    p.add_argument("--only", help="these parts (comma-separated)")
    args = p.parse_args(argv)
    try:
        first_text, end_text = args.trials.split(":")
        first, end = int(first_text or 0), (int(end_text) if end_text else None)
        if first < 0 or (end is not None and end <= first):
            raise ValueError
    except ValueError:
        raise SystemExit(
            f"--trials must be FIRST:END with 0 <= FIRST < END, got {args.trials!r}"
        ) from None
    for folder in (args.run, args.reference):
        if not folder.is_dir():
            raise SystemExit(f"{folder} is not a folder of the parts suite's CSVs")
    only = set(args.only.split(",")) if args.only else None
    rows = paired_rows(args.run, args.reference, first, end, only)
    if not rows:
        raise SystemExit(f"{args.run} and {args.reference} hold no part's trials in common")
    sys.stdout.write(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
