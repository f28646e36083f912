"""How much of the CPU engine's NumPy pass holds the GIL: the pass alone in 1 and in 2 threads.

    python benchmarks/gil.py [--trials 1000] [--rows 256] [--seconds 5]

The CPU engine runs one lane (Python thread) per core; each lane's physics (`Batch.step`) runs
without the GIL, its NumPy pass (Jacobians, wrench, controller) partly with it. This captures the
inputs of one real control period of `--rows` live trials (baseline, square 50 mm, ±3 mm / ±4
deg), then runs the same pass over and over in one thread, then in two threads at once, and
prints passes/s. With two cores free, two threads give `r` times one thread's rate: r = 2 when
nothing holds the GIL, 1 when everything does; the share that holds it is about 1/r (for r < 2).
Run it on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import os
import threading
import time

import numpy as np

from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials


class _Captured(Exception):
    """Raised by the observer to stop the engine once a lane has been captured."""


def capture(trials: int, rows: int) -> dict:
    """A lane of the engine, stopped at its first control period with at least `rows` live rows
    (after 200 steps), and that period's measurements."""
    task = TaskConfig(shapes=("square",), linear_error=0.003, angular_error=np.deg2rad(4.0))
    specs = sample_trials(task, 0, trials)
    params = as_controller_params(baseline_params(), len(specs))
    got: dict = {}

    def observe(lane, live, wrench):
        if lane.n >= rows and lane.step[0] >= 200:
            got.update(lane=lane, m=lane.measured)
            raise _Captured

    config = TrialConfig(time_limit_s=2.0, end_settled=False)
    try:
        cpu_engine.run_on_cpu(specs, params, config, threads=1, observer=observe)
    except _Captured:
        return got
    raise SystemExit(f"gil.py: error: no control period had {rows} live rows")


def numpy_pass(c: dict) -> np.ndarray:
    """The engine's own pass of one control period (`Lane.advance`), without the physics."""
    return c["lane"].advance(c["m"])[1]


def rate(lanes: list[dict], seconds: float) -> float:
    """Passes per second of one thread per captured lane, running for `seconds`."""
    counts = [0] * len(lanes)
    stop = threading.Event()
    start_line = threading.Barrier(len(lanes) + 1)

    def work(k):
        start_line.wait()
        while not stop.is_set():
            numpy_pass(lanes[k])
            counts[k] += 1

    pool = [threading.Thread(target=work, args=(k,)) for k in range(len(lanes))]
    for t in pool:
        t.start()
    start_line.wait()
    begin = time.perf_counter()
    time.sleep(seconds)
    stop.set()
    for t in pool:
        t.join()
    return sum(counts) / (time.perf_counter() - begin)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=1000)
    p.add_argument("--rows", type=int, default=256)
    p.add_argument("--seconds", type=float, default=5.0)
    args = p.parse_args()
    one_lane = capture(args.trials, args.rows)
    other_lane = capture(args.trials, args.rows)  # two threads, two lanes: no shared state
    numpy_pass(one_lane)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    one = rate([one_lane], args.seconds)
    two = rate([one_lane, other_lane], args.seconds)
    r = two / one
    print(f"{args.rows} rows per pass: 1 thread {one:.0f} passes/s ({1e6 / one:.0f} µs per pass, "
          f"{1e6 / one / args.rows:.2f} µs per row); 2 threads {two:.0f} passes/s: r = {r:.2f}, "
          f"GIL-held share ~ {min(1.0, 1 / r):.2f}")  # fmt: skip
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
