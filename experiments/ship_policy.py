"""Copy a finished training run's portable policy into policies/NAME, with its provenance.

    python experiments/ship_policy.py runs/quick quick --commit 65ba884 \
        --command "python train.py --skill search --trials 4096 --out runs/quick"

policies/NAME gets policy.npz, manifest.json, config.json, metrics.csv and training_curve.png
(what the run wrote; no checkpoints), and provenance.json: the full commit whose code trained
it, the command, the machine, the training's wall time and trials (from metrics.csv). Every
CLI then takes `--policy NAME` (mjx_peg/policy/shipped.py).
"""

from __future__ import annotations

import argparse
import csv
import json
import platform
import shutil
import subprocess
from pathlib import Path

from mjx_peg.policy.export import load_policy
from mjx_peg.policy.shipped import SHIPPED_DIR

FILES = ("policy.npz", "manifest.json", "config.json", "metrics.csv", "training_curve.png")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="a finished training run directory")
    p.add_argument("name", help="the shipped name (quick, paper, transfer)")
    p.add_argument("--commit", required=True, help="the commit whose code trained it")
    p.add_argument("--command", required=True, help="the command that trained it")
    p.add_argument("--note", default="", help="anything else a reader needs")
    args = p.parse_args(argv)
    load_policy(args.run)  # a complete, readable policy, or one clear line
    sha = subprocess.run(["git", "rev-parse", "--verify", args.commit + "^{commit}"],
                         capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    with open(args.run / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    out = SHIPPED_DIR / args.name
    out.mkdir(parents=True, exist_ok=True)
    for name in FILES:
        shutil.copy2(args.run / name, out / name)
    provenance = {
        "commit": sha,
        "command": args.command,
        "machine": f"{platform.machine()}, {platform.processor() or 'cpu'}, Python "
        f"{platform.python_version()}",
        "iterations": len(rows),
        "trials": int(rows[-1]["trials"]),
        "wall_s": float(rows[-1]["wall_s"]),
        "note": args.note,
    }
    (out / "provenance.json").write_text(json.dumps(provenance, indent=2) + "\n")
    print(f"shipped {args.run} as {out} ({provenance['trials']} trials, commit {sha[:10]})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
