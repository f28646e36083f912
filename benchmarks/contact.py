"""Credible contact (issue 18): success and contact metrics of a controller on a fixed set.

    python benchmarks/contact.py [--policy baseline|RUN_DIR] [--sensor VARIANT] [--trials 500]
        [--time-limit 60] [--seed 1] [--first] [--full-time-limit] [--threads N]
        [--processes N] [--csv FILE]

The set: circle + square 50 mm (`--shapes`), +-4 mm / +-6 deg, `sample_trials(seed)`, the C engine
(`mujoco.batch` lanes, one per core by default), the default TrialConfig (the UR5e's F/T
pipeline, the compliance damping, the 2 s approach, the 150 N protective stop; failures that have
settled end early unless --full-time-limit). Prints success, protective stops, settled failures,
the peak sensed force (median, p99) and the chatter (mean |dF| of the true axial force over the
last second of trials longer than 1.2 s: median and the share under 5 N), the wall time and the
physics steps per second. `--first` runs the first hand-tuned baseline (k = 300, compliance
1e-3 m/N and 0.05 rad/(N m), +-3e-3 m/(N m) moment-to-shift) instead of the current one.
`--policy RUN_DIR` runs a trained policy (its 38 numbers for each trial's observation).
`--sensor` changes the F/T pipeline of every trial (issue 18's robustness check): `nofilter`
(no low-pass), `cutoff0.5` / `cutoff2` (the cutoff halved / doubled), `delay+2` (two more
control periods of latency), `noise2` (the noise doubled). `--csv` writes one row per trial
(for paired comparisons of two runs of the same set).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.params import ControllerParams, vector_from_controller
from mjx_peg.skill.sensor import SensorConfig
from mjx_peg.world.constants import HOLE_DEPTH
from mjx_peg.world.task import TaskConfig, sample_trials


def first_baseline() -> np.ndarray:
    """(38,) the hand-tuned baseline before issue 18."""
    c = np.diag([1e-3, 1e-3, 1e-3, 0.05, 0.05, 0.01])
    c[1, 3], c[0, 4] = 3e-3, -3e-3
    k = np.asarray(300.0)
    return np.asarray(vector_from_controller(ControllerParams(k, k, c)))


def sensor_variant(name: str) -> SensorConfig:
    """The nominal UR5e pipeline with one thing changed (issue 18's robustness variants)."""
    s = SensorConfig()
    return {
        "nominal": s,
        "nofilter": s.replace(cutoff_hz=math.inf),
        "cutoff0.5": s.replace(cutoff_hz=s.cutoff_hz * 0.5),
        "cutoff2": s.replace(cutoff_hz=s.cutoff_hz * 2.0),
        "delay+2": s.replace(delay_steps=s.delay_steps + 2),
        "noise2": s.replace(force_noise=2 * s.force_noise, torque_noise=2 * s.torque_noise),
    }[name]


SENSOR_VARIANTS = ("nominal", "nofilter", "cutoff0.5", "cutoff2", "delay+2", "noise2")


def write_csv(path: str, result, specs) -> None:
    """One row per trial; where the peg tip ended: its depth below the board top (mm) and its
    distance from the hole axis (mm)."""
    columns = ("success", "time_s", "peak_force", "chatter", "protective_stop", "settled",
               "unstable", "steps")  # fmt: skip
    depth = (HOLE_DEPTH - result.final_tip_pos[:, 2]) * 1000
    off_axis = np.linalg.norm(result.final_tip_pos[:, :2] - specs.board_pos, axis=1) * 1000
    rows = [",".join(("trial",) + columns + ("tip_depth_mm", "tip_off_axis_mm"))]
    for k in range(len(result)):
        values = [getattr(result, c)[k] for c in columns] + [depth[k], off_axis[k]]
        rows.append(",".join([str(k)] + [f"{float(v):.6g}" for v in values]))
    with open(path, "w") as f:
        f.write("\n".join(rows) + "\n")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=500)
    p.add_argument("--time-limit", type=float, default=60.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--first", action="store_true", help="the baseline before issue 18")
    p.add_argument("--full-time-limit", action="store_true", help="run every failure to the limit")
    p.add_argument("--threads", type=int, default=None, help="lanes (default: every core)")
    p.add_argument("--processes", type=int, default=None, help="lanes in worker processes")
    p.add_argument("--policy", default="baseline", help="'baseline' or a training run directory")
    p.add_argument("--sensor", default="nominal", choices=SENSOR_VARIANTS)
    p.add_argument("--csv", help="write one row per trial here")
    p.add_argument("--shapes", default="circle,square", help="comma-separated (50 mm each)")
    args = p.parse_args()
    task = TaskConfig(shapes=tuple(args.shapes.split(",")), sizes=(0.05,), linear_error=0.004,
                      angular_error=math.radians(6.0))  # fmt: skip
    specs = sample_trials(task, args.seed, args.trials)
    if args.policy != "baseline":
        from mjx_peg.policy.export import load_policy

        vec = load_policy(args.policy).controller_vectors(specs)
        label = f"policy {args.policy}"
    else:
        vec = first_baseline() if args.first else baseline_params()
        label = f"{'first' if args.first else 'current'} baseline"
    start = time.perf_counter()
    config = TrialConfig(
        time_limit_s=args.time_limit,
        end_settled=not args.full_time_limit,
        sensor=sensor_variant(args.sensor),
    )
    result = run_trials(specs, vec, engine="mujoco", config=config, threads=args.threads,
                        processes=args.processes)  # fmt: skip
    wall = time.perf_counter() - start
    steps = int(result.steps.sum())
    times = result.time_s[result.success]
    p10, p50, p90 = np.percentile(times, [10, 50, 90]) if times.size else (np.nan,) * 3
    print(
        f"{label}, sensor {args.sensor}, {args.shapes} 50 mm, {args.trials} trials, seed "
        f"{args.seed}, {args.time_limit:g} s"
        f"{', every failure to the limit' if args.full_time_limit else ''}: {result.summary()}"
    )
    print(f"time to insert p10 / p50 / p90: {p10:.2f} / {p50:.2f} / {p90:.2f} s; wall {wall:.0f} s "
          f"for {steps:,} physics steps ({steps / wall:,.0f} steps/s)")  # fmt: skip
    if args.csv:
        write_csv(args.csv, result, specs)


if __name__ == "__main__":
    main()
