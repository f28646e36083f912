"""Period jitter of the UR5e adapter's 500 Hz loop on this machine, with the runtime's compute time.

    python benchmarks/ur5e_loop.py [--seconds 10] [--write]

Runs `run_skill` through `UR5eArm` against the simulated UR5e in real time (`SimulatedUR5e(
realtime=True)`: `waitPeriod` sleeps to the next 2 ms tick on the wall clock, as ur_rtde's does)
for `--seconds` of a commanded trial (the baseline, circle 50 mm, ±2 mm, no grasp error; no end
test, no settle test, so the loop runs the whole time). Reports the period between two readings
and the work of one period (reading to command), each p50 / p99 / max, and splits the work into
the adapter's reading (RTDE getters, DH kinematics, H and h), the simulated robot's own physics
inside it (which a real arm does not spend on this computer) and the runtime's compute.
`--write` replaces the "## UR5e adapter loop" section of BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import gc
import os
import time

import numpy as np
from _report import ROOT, cpu_name, write_section  # benchmarks/ is on sys.path when run

from mjx_peg.engines.trial import TrialConfig
from mjx_peg.robot.arm_model import MujocoArmModel
from mjx_peg.robot.runtime import HoleEstimate, SkillRuntime, run_skill
from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.robot.sim_ur5e import SimulatedUR5e
from mjx_peg.robot.ur5e import UR5eArm
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials

HEADING = "## UR5e adapter loop"


class TimedSimArm(SimArm):
    """SimArm that adds up the time of its reads (the simulated robot's physics)."""

    spent: list[float]

    def read(self):
        t0 = time.perf_counter()
        state = super().read()
        self.spent.append(time.perf_counter() - t0)
        return state


class TimedArm(UR5eArm):
    """UR5eArm that records the time of each `read` after the period's wait."""

    reads: list[float]

    def _close_period(self) -> None:
        super()._close_period()
        self._read_start = time.perf_counter()

    def read(self):
        self._read_start = time.perf_counter()
        state = super().read()
        self.reads.append(time.perf_counter() - self._read_start)
        return state


def measure(seconds: float, no_gc: bool) -> dict:
    specs = sample_trials(
        TaskConfig(shapes=("circle",), linear_error=0.002, angular_error=0.0), 0, 1
    )
    specs.grasp_error[:] = 0.0
    sim = TimedSimArm(specs, 0)
    sim.spent = []
    robot = SimulatedUR5e(sim, realtime=True)
    arm = TimedArm(robot.control, robot.receive, robot.dashboard, MujocoArmModel("circle", 0.05))
    arm.reads = []
    arm.check_ready()
    config = TrialConfig(time_limit_s=seconds, end_settled=False)
    runtime = SkillRuntime(baseline_params(), HoleEstimate.of_trial(specs, 0), config)
    if no_gc:
        gc.collect()
        gc.disable()
    try:
        run = run_skill(arm, runtime, done=lambda state: False)
    finally:
        gc.enable()
    n = run.commands
    ms = lambda v: 1000 * np.asarray(v, dtype=np.float64)  # noqa: E731
    period, work = ms(arm.log["period_s"][1:n]), ms(arm.log["work_s"][:n])
    reads, physics = ms(arm.reads[:n]), ms(sim.spent[:n])
    over, longest, streak = work > 1000 * arm.period, 0, 0
    for late in over:
        streak = streak + 1 if late else 0
        longest = max(longest, streak)
    return dict(run=run, period=period, work=work, read=reads, physics=physics,
                compute=work - reads, missed=int(over.sum()), longest=longest)  # fmt: skip


def row(name: str, values: np.ndarray) -> str:
    p50, p99, top = np.percentile(values, [50, 99, 100])
    return f"| {name} | {p50:.3f} | {p99:.3f} | {top:.3f} |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument(
        "--no-gc", action="store_true", help="Python's garbage collector off in the loop"
    )
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    results = {gc_off: measure(args.seconds, gc_off) for gc_off in (False, True)}
    lines = [
        HEADING,
        "",
        f"`UR5eArm` against the simulated UR5e in real time (`waitPeriod` on the wall clock), "
        f"{args.seconds:g} s at 500 Hz of a commanded trial (baseline, circle 50 mm), one process, "
        f"on {cpu_name()} ({os.cpu_count()} cores, shared; nothing else measured at the time). "
        "Milliseconds. `work` is one period's reading-to-command time: the adapter's `read` "
        "(ur_rtde getters, DH kinematics, H and h, the checks; it includes the simulated robot's "
        "own physics, which a real UR5e spends on its controller) plus the runtime's compute. "
        f"Command: `python benchmarks/ur5e_loop.py --seconds {args.seconds:g} --write`.",
        "",
    ]
    for gc_off, r in results.items():
        lines += [
            f"Python's garbage collector {'off (gc.disable) during the loop' if gc_off else 'on'}: "
            f"{r['run'].commands} commands, {r['missed']} periods whose work overran 2 ms, at most "
            f"{r['longest']} in a row; the run {r['run'].stopped or 'ran its whole time'}.",
            "",
            "| ms | p50 | p99 | max |",
            "|---|---|---|---|",
            row("period (reading to reading)", r["period"]),
            row("work (reading to command)", r["work"]),
            row("adapter `read`", r["read"]),
            row("of it, the simulated robot's physics", r["physics"]),
            row("runtime compute (`SkillRuntime`) and g(q)", r["compute"]),
            "",
        ]
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_section(ROOT / "BENCHMARKS.md", HEADING, text)


if __name__ == "__main__":
    main()
