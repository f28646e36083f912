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
from mjx_peg.skill.control_step import Measurement, Skill, skill_torque
from mjx_peg.world.task import TaskConfig, sample_trials


def capture(trials: int, rows: int) -> dict:
    """Copies of one lane's inputs at the first control period with at least `rows` rows."""
    task = TaskConfig(shapes=("square",), linear_error=0.003, angular_error=np.deg2rad(4.0))
    specs = sample_trials(task, 0, trials)
    params = as_controller_params(baseline_params(), len(specs))
    got: dict = {}

    def observe(lane, live, wrench):
        if got or lane.n < rows or lane.step[0] < 200:
            return
        n, m = rows, lane.measured
        got.update(
            m={k: np.array(v[:n]) for k, v in m._asdict().items()},
            skill=Skill(*(np.array(a[:n]) for a in (lane.goal_pos, lane.goal_rot, lane.y0,
                                                    lane.k_y, lane.d_y, lane.compliance))),
            tare=np.array(lane.tare[:n]), step=np.array(lane.step[:n]),
            control=lane.control, basis=lane.basis, config=lane.config,
        )  # fmt: skip

    config = TrialConfig(time_limit_s=2.0, end_settled=False)
    cpu_engine.run_trials(specs, params, config, threads=1, observer=observe)
    if not got:
        raise SystemExit(f"gil.py: error: no control period had {rows} live rows")
    return got


def numpy_pass(c: dict) -> np.ndarray:
    """The engine's pass of one control period (as `_Lane._control`), without the physics."""
    m = c["m"]
    tcp_pos, ft_pos, ft_rot = m["site_pos"][:, 0], m["site_pos"][:, 2], m["site_rot"][:, 1]
    jac, jac_dot = cpu_engine.jacobians(m["cdof"], m["cdof_dot"], m["cvel"], m["com"], tcp_pos)
    wrench = cpu_engine.wrench_in_goal_frame(
        m["ft"][:, :3], m["ft"][:, 3:], c["tare"], ft_rot, ft_pos - tcp_pos, c["skill"].goal_rot
    )
    meas = Measurement(
        t=c["step"] * c["config"].timestep,
        tcp_pos=np.ascontiguousarray(tcp_pos),
        tcp_rot=np.ascontiguousarray(m["site_rot"][:, 0]),
        jac=jac,
        jdot_qdot=(jac_dot @ m["qvel"][..., None])[..., 0],
        qvel=m["qvel"],
        mass=m["mass"],
        bias=m["bias"],
        wrench=wrench,
    )
    return skill_torque(c["control"], c["skill"], c["basis"], meas)


def rate(c: dict, threads: int, seconds: float) -> float:
    """Passes per second of `threads` threads running the pass for `seconds`."""
    counts = [0] * threads
    stop = threading.Event()
    start_line = threading.Barrier(threads + 1)

    def work(k):
        start_line.wait()
        while not stop.is_set():
            numpy_pass(c)
            counts[k] += 1

    pool = [threading.Thread(target=work, args=(k,)) for k in range(threads)]
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
    c = capture(args.trials, args.rows)
    numpy_pass(c)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    one = rate(c, 1, args.seconds)
    two = rate(c, 2, args.seconds)
    r = two / one
    print(f"{args.rows} rows per pass: 1 thread {one:.0f} passes/s ({1e6 / one:.0f} µs per pass, "
          f"{1e6 / one / args.rows:.2f} µs per row); 2 threads {two:.0f} passes/s: r = {r:.2f}, "
          f"GIL-held share ~ {min(1.0, 1 / r):.2f}")  # fmt: skip
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
