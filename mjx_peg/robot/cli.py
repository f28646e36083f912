"""Run a policy through the robot runtime on the simulated arm, or on a real UR5e.

    python -m mjx_peg.robot --policy runs/paper --trials 20 --command-hz 500
    python -m mjx_peg.robot --robot-ip 192.168.1.10 --hole 450,-120,30 --shape circle --shadow

Simulated (the default):
Each trial samples a board, errors and a start like the evaluation (`task.sample_trials`), builds
a `SimArm`, and runs `run_skill` with the numbers the policy gives for the estimated hole. The
command rate must divide the 500 Hz physics (500, 250, 166.7, 125, 100, ... Hz); torques are held
between commands. The default is 500 Hz, the rate at which a UR e-Series controller (the UR5e)
exchanges RTDE data; the paper sent effort commands at 125 Hz, and there the skill, whose approach
was tuned at 500 Hz, protective-stops at touchdown in most trials (README "On an arm"). Writes
`runs.csv` under --out, one row per trial as it ends (a crash keeps the finished ones), and
`skill.json`, the skill the trials ran (its name and every constant); an earlier runs.csv is
replaced only with --force, which moves it aside.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

from mjx_peg import cli, outdir
from mjx_peg.errors import UsageError
from mjx_peg.policy.shipped import resolve_policy
from mjx_peg.skill.search import SKILL_DESCRIPTIONS
from mjx_peg.skill.skill_cli import skill_constant
from mjx_peg.world import constants
from mjx_peg.world.constants import GRASP_MODELS

PROG = "python -m mjx_peg.robot"
PHYSICS_HZ = 1.0 / constants.TIMESTEP


COLUMNS = ("trial", "success", "time_s", "commands", "stopped", "protective_stop", "settled",
           "peak_force_n", "chatter_n")  # fmt: skip
RESULTS = "runs.csv"
SKILL_FILE = "skill.json"  # the skill the runs ran: {"name", "constants"}


def build_parser() -> argparse.ArgumentParser:
    from mjx_peg.world.parts import HOLE_SCALE_HELP

    p = cli.Parser(prog=PROG, description=__doc__.splitlines()[0])
    p.add_argument(
        "--policy",
        default="baseline",
        help="RUN_DIR holding policy.npz, a shipped policy's name (policies/), or baseline",
    )
    p.add_argument("--shape", choices=constants.SHAPES, default="circle")
    p.add_argument("--size", type=cli.SIZE_MM, default=50.0, help="size S (default 50)")
    p.add_argument("--hole-scale", default="paper", help=HOLE_SCALE_HELP)
    p.add_argument("--linear-mm", type=cli.LINEAR_MM, default=2.0, help="± linear error range")
    p.add_argument("--angular-deg", type=cli.ANGULAR_DEG, default=3.0,
                   help="± angular error range (with --robot-ip: the uncertainty of --hole's yaw, "
                   "which a skill with yaw_scale=uncertainty sweeps)")  # fmt: skip
    p.add_argument("--trials", type=cli.TRIALS, default=10, help="default 10")
    p.add_argument("--seed", type=cli.SEED, default=0, help="default 0")
    cli.add_grasp_model_option(p, GRASP_MODELS, "board")
    cli.add_skill_option(p, SKILL_DESCRIPTIONS)
    cli.add_skill_constant_option(p, skill_constant)
    p.add_argument(
        "--command-hz",
        type=cli.number(0, PHYSICS_HZ, "Hz", lo_open=True),
        default=500.0,
        help="torque command rate, a divisor of the 500 Hz physics (default 500, the UR5e's RTDE "
        "rate; the paper's UR5e took effort commands at 125)",
    )
    p.add_argument(
        "--actuator-lag-ms",
        type=cli.number(0, 100, "ms"),
        default=0.0,
        help="a first-order lag from the torque command to the joint torque (default 0: none; "
        "5: a real arm's drives, a robustness variant)",
    )
    p.add_argument(
        "--time-limit", type=cli.TIME_LIMIT_S, default=60.0, help="simulated time per trial"
    )
    p.add_argument("--out", type=cli.nonempty_path, default=Path("runs/robot"))
    p.add_argument(
        "--force",
        action="store_true",
        help=f"replace {RESULTS} in --out: the earlier one is moved aside "
        f"({RESULTS}.replaced-DATE-TIME)",
    )
    p.add_argument("--no-progress", action="store_true")
    arm = p.add_argument_group(
        "a real UR5e (one insertion at --hole; robot/ur5e_cli.py, needs the robot extra: "
        'pip install -e ".[robot]")'
    )
    arm.add_argument("--robot-ip", help="the UR5e's address (IP or host name): run on the arm")
    arm.add_argument("--hole", metavar="X,Y,YAW", help="estimated hole centre (mm) and yaw (deg)")
    arm.add_argument(
        "--shadow", action="store_true", help="read the arm, compute and log torques, send nothing"
    )
    arm.add_argument(
        "--dry-run", action="store_true", help="no connection: print the plan and the free motion"
    )
    arm.add_argument(
        "--rehearse",
        action="store_true",
        help="the same path against a simulated UR5e behind ur_rtde's interface (no hardware)",
    )
    arm.add_argument(
        "--friction-comp",
        action="store_true",
        help="let the controller add its joint friction compensation to the torques",
    )
    arm.add_argument(
        "--model",
        choices=("mujoco", "controller"),
        default="mujoco",
        help="where H and h come from: the training scene (default) or the UR controller",
    )
    return p


def _check_host(text: str) -> None:
    """ValueError unless `text` is an IPv4/IPv6 address or a host name."""
    import ipaddress
    import re

    try:
        ipaddress.ip_address(text)
    except ValueError:
        host = r"(?=.{1,253}$)[A-Za-z0-9]([A-Za-z0-9-]{0,62})(\.[A-Za-z0-9-]{1,63})*"
        if not re.fullmatch(host, text):
            raise UsageError(f"--robot-ip: not an IP address or host name: {text!r}") from None


def command_steps(hz: float, time_limit: float = math.inf) -> int:
    """Physics steps per command for a rate that divides the physics rate and whose period fits
    in `time_limit` (s); UsageError if not."""
    if not (math.isfinite(hz) and 0 < hz <= PHYSICS_HZ):
        raise UsageError(f"--command-hz must be in (0, {PHYSICS_HZ:g}], got {cli.number_text(hz)}")
    if 1.0 / hz > time_limit:  # also every rate too small to divide by (5e-324 Hz)
        raise UsageError(
            f"--command-hz {hz:g} commands every {1.0 / hz:g} s, longer than the --time-limit "
            f"of {time_limit:g} s: give at least {1.0 / time_limit:g} Hz"
        )
    steps = round(PHYSICS_HZ / hz)
    if abs(PHYSICS_HZ / steps - hz) > 1e-3:
        raise UsageError(
            f"--command-hz must divide the {PHYSICS_HZ:g} Hz physics "
            f"(500, 250, 166.7, 125, 100, ...), got {cli.number_text(hz)}"
        )
    return steps


def _setup(args):
    from mjx_peg.world.parts import parse_hole_scale
    from mjx_peg.world.task import TaskConfig

    steps = command_steps(args.command_hz, args.time_limit)
    task = TaskConfig.from_mm_deg((args.shape,), args.size, args.linear_mm, args.angular_deg,
                                  grasp_model=args.grasp_model,
                                  hole_scale=parse_hole_scale(args.hole_scale))  # fmt: skip
    if not args.policy:
        raise UsageError("--policy must be a run directory or baseline, got an empty string")
    args.policy = resolve_policy(args.policy)
    return task, steps


def _has_rows(path: Path) -> bool:
    """Whether a results file holds any result (more than a header)."""
    if not path.is_file():  # absent, or something that is not a file (kept, never read)
        return path.exists() or path.is_symlink()
    with open(path, "rb") as f:
        return len(f.read(1 << 16).splitlines()) > 1


@cli.entry(PROG)
def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    real = args.robot_ip is not None or args.dry_run or args.rehearse
    for flag, given in (("--model controller", args.model == "controller"),
                        ("--friction-comp", args.friction_comp)):  # fmt: skip
        if given and args.robot_ip is None and not args.rehearse:
            raise UsageError(f"{flag} asks a UR5e's controller: give --robot-ip (or --rehearse)")
    if real or args.shadow or args.hole:
        if args.robot_ip is not None:
            _check_host(args.robot_ip)
        if not real:
            raise UsageError("--hole and --shadow need --robot-ip, --rehearse or --dry-run")
        if args.hole is None:
            raise UsageError("--robot-ip, --rehearse and --dry-run need --hole X,Y,YAW")
        if args.robot_ip and args.rehearse:
            raise UsageError("--rehearse runs on the simulated UR5e: drop --robot-ip")
        if args.dry_run and (args.shadow or args.rehearse):
            raise UsageError("--dry-run connects to nothing: drop --shadow and --rehearse")
        if args.actuator_lag_ms:
            raise UsageError("--actuator-lag-ms is a property of the simulated arm: drop it")
        from mjx_peg.robot import ur5e_cli

        return ur5e_cli.run(args, PROG)
    from mjx_peg.policy.export import choose_skill, load_policy

    task, steps = _setup(args)
    policy = args.policy if args.policy == "baseline" else load_policy(args.policy)
    skill = choose_skill(args.skill, policy, args.skill_constant or ())
    # The output location, before any trial: never the policy, one writer at a time, no earlier
    # result replaced without --force (moved aside then), writable; then one row per trial as
    # it ends.
    outdir.check_apart(args.out, {"--policy": args.policy})
    with outdir.exclusive(args.out):
        return _simulate(args, task, steps, policy, skill)


def _simulate(args, task, steps: int, policy, skill) -> int:
    """The trials of the simulated arm, into --out (held)."""
    import numpy as np

    from mjx_peg.engines.trial import (
        CHATTER_LIMIT_N,
        CHATTER_MIN_TIME_S,
        TrialConfig,
        chatter_counted,
        smooth_pct,
    )
    from mjx_peg.outdir import write_json
    from mjx_peg.robot import runtime, sim_arm
    from mjx_peg.world.parts import fit_text
    from mjx_peg.world.task import sample_trials

    results = args.out / RESULTS
    if _has_rows(results) or results.is_symlink():
        outdir.refuse_or_move([results], args.force, lambda text: cli.note(PROG, text))
    outdir.prepare_dir(args.out)
    from mjx_peg.world import mujoco_log

    mujoco_log.send_to(args.out)
    specs = sample_trials(task, args.seed, args.trials)
    holes = [runtime.HoleEstimate.of_trial(specs, i) for i in range(len(specs))]
    vectors = [runtime.controller_vector(policy, hole) for hole in holes]
    write_json(args.out / SKILL_FILE, skill.record())
    config = TrialConfig(time_limit_s=args.time_limit, search=skill.config)
    rows, start = [], time.perf_counter()
    bar = None
    if not args.no_progress:
        from tqdm import tqdm

        bar = tqdm(total=len(specs), desc="trials", unit="trial", file=sys.stderr)
    try:
        with open(results, "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(COLUMNS)
            f.flush()
            try:
                for i, (vector, hole) in enumerate(zip(vectors, holes, strict=True)):
                    arm = sim_arm.SimArm(specs, i, command_steps=steps,
                                         success_height=config.success_height,
                                         actuator_lag_s=args.actuator_lag_ms / 1000.0)  # fmt: skip
                    skill_run = runtime.SkillRuntime(vector, hole, config)
                    run = runtime.run_skill(arm, skill_run, done=arm.inserted)
                    row = (i, int(run.success), f"{run.time_s:.3f}", run.commands, run.stopped,
                           int(run.protective_stop), int(run.stopped == "settled"),
                           f"{run.peak_force:.2f}", f"{arm.chatter():.3f}")  # fmt: skip
                    writer.writerow(row)
                    f.flush()  # a crash keeps every finished trial
                    rows.append(row)
                    if bar is not None:
                        bar.update(1)
            except KeyboardInterrupt:
                print(
                    f"{PROG}: interrupted after {len(rows)} of {len(specs)} trials; their rows are "
                    f"in {results}",
                    file=sys.stderr,
                )
                return cli.EXIT_INTERRUPTED
            finally:
                if bar is not None:
                    bar.close()
    except OSError as e:  # a full disk: named, and no runs.csv without a row left behind
        if not rows:
            results.unlink(missing_ok=True)
        if e.filename is not None:
            raise
        raise OSError(e.errno, e.strerror, str(results)) from None
    ok = np.array([r[1] for r in rows], dtype=bool)
    times = np.array([float(r[2]) for r in rows])
    median = f"{np.median(times[ok]):.2f} s" if ok.any() else "-"
    stops = sum(1 for r in rows if r[4])
    protective, settled = sum(r[5] for r in rows), sum(r[6] for r in rows)
    peak = np.array([float(r[7]) for r in rows])
    long = np.array([float(r[8]) for r in rows])[chatter_counted(times)]
    contact = (
        f"peak sensed force median {np.median(peak):.0f} N, chatter under {CHATTER_LIMIT_N:g} N "
        f"in {smooth_pct(long):.1f} % of the "
        f"{long.size} trials longer than {CHATTER_MIN_TIME_S:g} s"
        if rows
        else "-"
    )
    fit = fit_text(args.shape, task.hole_scale_range(args.shape)[0])
    print(
        f"{args.policy} on the simulated arm at {PHYSICS_HZ / steps:g} Hz commands, "
        f"{args.shape} {args.size:g} mm{fit}, "
        f"±{args.linear_mm:g} mm / ±{args.angular_deg:g} deg: "
        f"{int(ok.sum())}/{len(rows)} inserted ({100 * ok.mean():.1f} %), median time {median}, "
        f"{stops} stops ({protective} protective, {settled} settled); {contact}; "
        f"{time.perf_counter() - start:.0f} s wall; wrote {results}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
