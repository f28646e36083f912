"""A training run's policy at one of the checkpoints it keeps, exported as a policy folder.

    python experiments/export_checkpoint.py runs/generic/seed-0 --iteration 29 \
        --out runs/generic-seed-0-at-29

The trainer exports a run's policy when the run finishes; a run also keeps its last few Orbax
checkpoints (every minute of training and the last iteration). This writes OUT/config.json,
policy.npz and manifest.json (marked unfinished, with the trials it had trained on) from the
checkpoint after `--iteration`, so that eval.py, the experiments and the arm run the policy as it
was then, e.g. within a budget of trials that the run's iterations overshoot. An iteration the run
no longer keeps, or an OUT that is not a new or empty folder, is one line.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mjx_peg.errors import UsageError


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="a training run directory")
    p.add_argument("--iteration", type=int, required=True, help="a checkpoint the run keeps")
    p.add_argument("--out", type=Path, required=True, help="the policy folder to write")
    args = p.parse_args(argv)
    from mjx_peg.learn.trainer import export_checkpoint

    try:
        trials = export_checkpoint(args.run, args.iteration, args.out)
    except UsageError as e:
        print(f"export_checkpoint: {e}", file=sys.stderr)
        return 2
    print(f"{args.out}: the policy of {args.run} after iteration {args.iteration}, {trials:,} "
          "trials")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
