"""Latency of one command of the robot runtime (NumPy, unbatched), against the robot's period.

    python benchmarks/robot_step.py [--calls 5000] [--write]

Times `SkillRuntime.torque` (wrench to the goal frame, DMP, coupling, OSC torque, safety checks)
on readings of a simulated arm in the middle of a trial, one call at a time as on the robot's
computer, after 200 warm-up calls; also `SimArm.read` + `send` (the simulation's own cost, which
a real arm replaces by RTDE's). Reports the median and the 99th and 99.9th percentiles in
microseconds and the share of the 2 ms (500 Hz) and 8 ms (125 Hz) periods the median takes.
`--write` replaces the "## Robot runtime" section of BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _report import ROOT, cpu_name, write_section  # benchmarks/ is on sys.path when run

from mjx_peg.robot.runtime import HoleEstimate, SkillRuntime
from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials

HEADING = "## Robot runtime"


def measure(calls: int) -> dict:
    specs = sample_trials(TaskConfig(linear_error=0.002, angular_error=0.03), 0, 1)
    arm = SimArm(specs, 0)
    runtime = SkillRuntime(baseline_params(), HoleEstimate.of_trial(specs, 0))
    runtime.start(arm.read())
    for _ in range(200):  # warm-up, and into the movement
        arm.send(runtime.torque(arm.read()))
    torque_us, sim_us = [], []
    for _ in range(calls):
        t0 = time.perf_counter()
        state = arm.read()
        t1 = time.perf_counter()
        u = runtime.torque(state)
        t2 = time.perf_counter()
        arm.send(u)
        t3 = time.perf_counter()
        torque_us.append((t2 - t1) * 1e6)
        sim_us.append((t1 - t0 + t3 - t2) * 1e6)
    return {"torque": np.array(torque_us), "sim": np.array(sim_us)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=5000)
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    times = measure(args.calls)
    rows = []
    for name, label in (("torque", "`SkillRuntime.torque`"), ("sim", "`SimArm.read` + `send`")):
        t = times[name]
        med, p99, p999 = np.percentile(t, [50, 99, 99.9])
        shares = f"{med / 20:.1f} % | {med / 80:.1f} %"  # of 2000 us and 8000 us
        rows.append(f"| {label} | {med:.0f} | {p99:.0f} | {p999:.0f} | {shares} |")
        print(rows[-1])
    section = "\n".join(
        [
            HEADING,
            "",
            f"One command of the NumPy runtime, unbatched, on {cpu_name()} "
            f"({os.cpu_count()} cores, one thread), {args.calls} calls after 200 warm-up calls, "
            "readings of a simulated arm in free motion (`python benchmarks/robot_step.py "
            f"--calls {args.calls} --write`). Microseconds per call.",
            "",
            "| call | median | p99 | p99.9 | of 2 ms (500 Hz) | of 8 ms (125 Hz) |",
            "|---|---|---|---|---|---|",
            *rows,
            "",
        ]
    )
    if args.write:
        write_section(ROOT / "BENCHMARKS.md", HEADING, section)
        print(f"wrote the '{HEADING}' section of BENCHMARKS.md")


if __name__ == "__main__":
    main()
