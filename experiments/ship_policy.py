"""Copy a finished training run's portable policy into policies/NAME, with its provenance; or
record again which skill a shipped policy runs by default.

    python experiments/ship_policy.py runs/quick quick --commit 65ba884 \
        --command "python train.py --trials 4096 --out runs/quick"
    python experiments/ship_policy.py policies/paper paper --skill spiral
    python experiments/ship_policy.py policies/family family --skill spiral \
        --skill-constant yaw_scale=uncertainty

policies/NAME gets policy.npz, manifest.json, config.json, metrics.csv and training_curve.png
(what the run wrote; no checkpoints), and provenance.json: the full commit whose code trained
it, the command, the machine, the training's wall time and trials (from metrics.csv). Every
CLI then takes `--policy NAME` (mjx_peg/policy/shipped.py).

manifest.json also records the range of the training parts' features (`observation.part_range`,
from the training config, as the trainer writes it; the policy holds a part's features to it): a
policy shipped before the trainer wrote it gets it here.

`--skill` records in manifest.json the skill to run the policy with by default: the one its
published numbers used (default: the one it was trained with), with its constants as they are
now, each `--skill-constant NAME=VALUE` set on them. Given a shipped policy's own folder, only its
manifest.json and config.json are written again (the skill to run it with; the training config
with every field, the constants of the skill it trained with included); policy.npz and the
provenance stay as they are.
"""

from __future__ import annotations

import argparse
import csv
import json
import platform
import shutil
import subprocess
from pathlib import Path

from mjx_peg import cli
from mjx_peg.learn.config import TrainConfig
from mjx_peg.outdir import write_atomic, write_json
from mjx_peg.policy.export import MANIFEST_FILE, load_policy, part_range_json
from mjx_peg.policy.shipped import SHIPPED_DIR
from mjx_peg.skill.search import SKILLS, named_skill
from mjx_peg.skill.skill_cli import skill_constant

FILES = ("policy.npz", "manifest.json", "config.json", "metrics.csv", "training_curve.png")


def record_skill(folder: Path, skill: str | None, changes=()) -> str:
    """Write folder's manifest.json and config.json again: the skill to run it with (`skill`,
    default the trained one, its constants as they are now, with `changes`, (name, value) pairs
    of `--skill-constant`, set on them), the training parts' feature range and the training
    config in full. Returns the skill's name."""
    path = folder / MANIFEST_FILE
    layout = load_policy(folder).layout
    manifest = json.loads(path.read_text())
    trained = TrainConfig.from_json(manifest["config"])
    run = named_skill(skill) if skill else named_skill(trained.skill, trained.skill_constants)
    if changes:
        run = named_skill(run.name, run.config.replace(**dict(changes)))
    written = {}
    for key, value in manifest.items():  # the order save_policy writes: the skill, the config
        if key == "observation":
            part_range = part_range_json(layout, trained.part_range(layout))
            written[key] = {**value, "part_range": part_range}
        elif key == "config":
            written.update(skill=run.record(), config=trained.to_json())
        elif key != "skill":
            written[key] = value
    write_json(path, written)
    config = TrainConfig.from_json(json.loads((folder / "config.json").read_text()))
    write_atomic(folder / "config.json", config.dumps())
    load_policy(folder)  # it still reads
    return run.name


@cli.entry("ship_policy.py")
def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="a finished training run directory, or policies/NAME")
    p.add_argument("name", help="the shipped name (quick, paper, transfer)")
    p.add_argument("--commit", help="the commit whose code trained it (a run to copy)")
    p.add_argument("--command", help="the command that trained it (a run to copy)")
    p.add_argument("--note", default="", help="anything else a reader needs")
    p.add_argument(
        "--skill",
        choices=tuple(SKILLS),
        help="the skill to run it with by default (default: the one it trained with)",
    )
    cli.add_skill_constant_option(p, skill_constant)
    args = p.parse_args(argv)
    load_policy(args.run)  # a complete, readable policy, or one clear line
    out = SHIPPED_DIR / args.name
    if args.run.resolve() == out.resolve():
        name = record_skill(out, args.skill, args.skill_constant or ())
        print(f"{out}: runs the skill {name} by default; policy.npz unchanged")
        return 0
    if not (args.commit and args.command):
        p.error("copying a run needs --commit and --command")
    sha = subprocess.run(["git", "rev-parse", "--verify", args.commit + "^{commit}"],
                         capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    with open(args.run / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    out.mkdir(parents=True, exist_ok=True)
    for name in FILES:
        shutil.copy2(args.run / name, out / name)
    record_skill(out, args.skill, args.skill_constant or ())
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
