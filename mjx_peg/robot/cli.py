"""Run a policy through the robot runtime on the simulated arm, at the robot's command rate.

    python -m mjx_peg.robot --policy runs/paper --trials 20 --command-hz 125

Each trial samples a board, errors and a start like the evaluation (`task.sample_trials`), builds
a `SimArm`, and runs `run_skill` with the numbers the policy gives for the estimated hole. The
command rate must divide the 500 Hz physics (500, 250, 166.7, 125, 100, ... Hz); torques are held
between commands. Writes `runs.csv` (one row per trial) under --out.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np

from mjx_peg import cli
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.policy.export import PolicyError, load_policy
from mjx_peg.robot.runtime import HoleEstimate, SkillRuntime, controller_vector, run_skill
from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.world import constants
from mjx_peg.world.task import TaskConfig, sample_trials

PROG = "python -m mjx_peg.robot"
PHYSICS_HZ = 1.0 / constants.TIMESTEP


def _parser() -> argparse.ArgumentParser:
    p = cli.Parser(prog=PROG, description=__doc__.splitlines()[0])
    p.add_argument("--policy", default="baseline", help="RUN_DIR holding policy.npz, or baseline")
    p.add_argument("--shape", choices=constants.SHAPES, default="circle")
    p.add_argument("--size", type=float, default=50.0, help="size S in mm (default 50)")
    p.add_argument("--linear-mm", type=float, default=2.0, help="± linear error range (mm)")
    p.add_argument("--angular-deg", type=float, default=3.0, help="± angular error range (deg)")
    p.add_argument("--trials", type=int, default=10)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--command-hz", type=float, default=125.0,
                   help="torque command rate (default 125, the paper's UR5e)")  # fmt: skip
    p.add_argument("--time-limit", type=float, default=60.0, help="simulated s per trial")
    p.add_argument("--out", type=Path, default=Path("runs/robot"))
    p.add_argument("--no-progress", action="store_true")
    return p


def command_steps(hz: float) -> int:
    """Physics steps per command for a rate that divides the physics rate; ValueError if not."""
    if not (math.isfinite(hz) and 0 < hz <= PHYSICS_HZ):
        raise ValueError(f"--command-hz must be in (0, {PHYSICS_HZ:g}], got {hz:g}")
    steps = round(PHYSICS_HZ / hz)
    if abs(PHYSICS_HZ / steps - hz) > 1e-3:
        raise ValueError(
            f"--command-hz must divide the {PHYSICS_HZ:g} Hz physics "
            f"(500, 250, 166.7, 125, 100, ...), got {hz:g}"
        )
    return steps


def _setup(args):
    if args.trials < 1:
        raise ValueError(f"--trials must be >= 1, got {args.trials}")
    if not (args.time_limit > 0 and math.isfinite(args.time_limit)):
        raise ValueError(
            f"--time-limit must be a positive number of seconds, got {args.time_limit}"
        )
    if not (args.size > 0 and math.isfinite(args.size)):
        raise ValueError(f"--size must be a positive number of mm, got {args.size}")
    if args.linear_mm < 0 or args.angular_deg < 0:
        raise ValueError("error ranges must be >= 0")
    steps = command_steps(args.command_hz)
    task = TaskConfig.from_mm_deg((args.shape,), args.size, args.linear_mm, args.angular_deg)
    specs = sample_trials(task, args.seed, args.trials)
    if args.policy != "baseline" and not Path(args.policy).exists():
        raise ValueError(f"--policy {args.policy}: no such run directory")
    return specs, steps


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        specs, steps = _setup(args)
        policy = args.policy if args.policy == "baseline" else load_policy(args.policy)
        holes = [HoleEstimate.of_trial(specs, i) for i in range(len(specs))]
        vectors = [controller_vector(policy, hole) for hole in holes]
    except (*cli.USER_ERRORS, PolicyError) as exc:
        return cli.fail(PROG, exc)
    config = TrialConfig(time_limit_s=args.time_limit)
    args.out.mkdir(parents=True, exist_ok=True)
    rows, start = [], time.perf_counter()
    bar = None
    if not args.no_progress:
        from tqdm import tqdm

        bar = tqdm(total=len(specs), desc="trials", unit="trial", file=sys.stderr)
    for i, (vector, hole) in enumerate(zip(vectors, holes, strict=True)):
        arm = SimArm(specs, i, command_steps=steps, success_height=config.success_height)
        run = run_skill(arm, SkillRuntime(vector, hole, config), done=arm.inserted)
        rows.append((i, int(run.success), f"{run.time_s:.3f}", run.commands, run.stopped))
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    with open(args.out / "runs.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(("trial", "success", "time_s", "commands", "stopped"))
        writer.writerows(rows)
    ok = np.array([r[1] for r in rows], dtype=bool)
    times = np.array([float(r[2]) for r in rows])
    median = f"{np.median(times[ok]):.2f} s" if ok.any() else "-"
    stops = sum(1 for r in rows if r[4])
    print(
        f"{args.policy} on the simulated arm at {PHYSICS_HZ / steps:g} Hz commands, "
        f"{args.shape} {args.size:g} mm, ±{args.linear_mm:g} mm / ±{args.angular_deg:g} deg: "
        f"{int(ok.sum())}/{len(rows)} inserted ({100 * ok.mean():.1f} %), median time {median}, "
        f"{stops} safety stops; {time.perf_counter() - start:.0f} s wall; wrote {args.out}/runs.csv"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
