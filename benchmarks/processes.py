"""Lanes as threads of one process against lanes in separate processes (one GIL each).

    python benchmarks/processes.py [--trials 1000] [--rounds 2]

The engine runs its lanes as Python threads of the caller's process (`threads`, default every
core). This runs the trial benchmark's 1,000 trials (baseline, square 50 mm, ±3 mm / ±4 deg,
10 s, every failure to the limit) once as one process with 2 lanes, and once as 2 processes of
one lane each (trials k::2), alternating, and prints physics steps/s of each. It measures what a
process per lane would gain over threads on this machine; the engine itself does not do it.
"""

from __future__ import annotations

import argparse
import multiprocessing
import time

import numpy as np


def _job(args):
    part, parts, lanes, trials = args
    from mjx_peg.engines import mujoco as engine
    from mjx_peg.engines.trial import TrialConfig, as_controller_params
    from mjx_peg.skill.baseline import baseline_params
    from mjx_peg.world.task import TaskConfig, sample_trials

    task = TaskConfig(shapes=("square",), linear_error=0.003, angular_error=np.deg2rad(4.0))
    specs = sample_trials(task, 0, trials).take(np.arange(part, trials, parts))
    config = TrialConfig(time_limit_s=10.0, end_settled=False)
    warm = specs.take(np.arange(4))
    engine.run_on_cpu(warm, as_controller_params(baseline_params(), 4), config, threads=lanes)
    start = time.perf_counter()
    result = engine.run_on_cpu(
        specs, as_controller_params(baseline_params(), len(specs)), config, threads=lanes
    )
    return int(result.steps.sum()), time.perf_counter() - start, int(result.success.sum())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=1000)
    p.add_argument("--rounds", type=int, default=2)
    args = p.parse_args()
    ctx = multiprocessing.get_context("spawn")
    for _ in range(args.rounds):
        for parts, lanes in ((1, 2), (2, 1)):
            with ctx.Pool(parts) as pool:
                out = pool.map(_job, [(k, parts, lanes, args.trials) for k in range(parts)])
            steps, wall = sum(o[0] for o in out), max(o[1] for o in out)
            print(f"{parts} process(es) x {lanes} lane(s): {steps / wall:,.0f} steps/s, "
                  f"{sum(o[2] for o in out)} successes")  # fmt: skip


if __name__ == "__main__":
    main()
