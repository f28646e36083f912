"""Trial throughput of each engine, against the raw ceiling of bare mj_step on the same scene.

    python benchmarks/trials.py [--trials 200] [--workers N] [--mjx-trials 8] [--write]

Runs the hand-tuned baseline on `--trials` square 50 mm trials at 3 mm / 4 deg on the mujoco
engine, in this process (1 worker) and on `--workers` worker processes (default: every core),
and reports physics steps/s and trials/s. In the same run, the ceiling: the states the engine
visited (a snapshot every `--replay-every` steps, contacts included) are replayed with plain
`mj_step` and the recorded torques held, no controller, on as many processes as the engine used.
It also times a near-empty call (the fixed cost of a call) and profiles one in-process batch by
part (each part wrapped in a timer, the timer's own cost subtracted). The mjx engine is timed on
`--mjx-trials` trials (compile time reported apart). `--write` replaces the "## Trial engines"
section of BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import collections
import multiprocessing
import os
import time

import mujoco
import numpy as np
from _report import ROOT, cpu_name, write_section  # benchmarks/ is on sys.path when run

from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world import constants, scene
from mjx_peg.world.task import TaskConfig, sample_trials

STATE = mujoco.mjtState.mjSTATE_INTEGRATION


def time_engine(specs, params, config, workers):
    start = time.perf_counter()
    result = cpu_engine.run_trials(specs, params, config, workers=workers)
    return result, time.perf_counter() - start


def call_overhead(specs, params, workers, calls=20):
    """Median wall time (s) of a call running 2 trials of one step each."""
    config = TrialConfig(time_limit_s=TrialConfig().timestep)
    two, times = specs.take(np.arange(2)), []
    for _ in range(calls):
        start = time.perf_counter()
        cpu_engine.run_trials(two, params, config, workers=workers)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def record_states(specs, params, config, every):
    """(spec index, state) snapshots of the engine's trials, every `every` steps."""
    snaps = []

    def observe(batch, rows, wrench):
        for i in rows:
            if batch.step[i] % every == 0:
                m, d, _ = batch.current[i]
                state = np.empty(mujoco.mj_stateSize(m, STATE))
                mujoco.mj_getState(m, d, state, STATE)
                snaps.append((int(batch.spec_index[i]), state))

    cpu_engine.run_trials(specs, params, config, workers=1, observer=observe)
    return snaps


def _replay_part(specs, snaps, every, barrier):
    """Steps/s of bare mj_step from each snapshot for `every` steps (run in a worker process)."""
    envs, jobs = {}, []
    for index, state in snaps:
        key = (constants.SHAPES[int(specs.shape_id[index])], float(specs.size[index]))
        if key not in envs:
            m = scene.load_model(*key)
            envs[key] = (m, mujoco.MjData(m))
        jobs.append((*envs[key], index, state))
    barrier.wait()
    start = time.perf_counter()
    for m, d, index, state in jobs:
        scene.set_board_pose(m, *specs.board_pos[index], specs.board_yaw[index])
        scene.set_grasp(m, *specs.grasp_error[index])
        scene.set_friction(m, specs.friction[index])
        mujoco.mj_setState(m, d, state, STATE)
        for _ in range(every):
            mujoco.mj_step(m, d)
    return len(jobs) * every, time.perf_counter() - start


def replay(specs, snaps, every, processes):
    """Bare mj_step from every snapshot on `processes` processes started together; steps/s."""
    ctx = multiprocessing.get_context("spawn")
    with ctx.Manager() as manager, ctx.Pool(processes) as pool:
        barrier = manager.Barrier(processes)
        parts = [(specs, snaps[k::processes], every, barrier) for k in range(processes)]
        done = pool.starmap(_replay_part, parts)
    return sum(steps for steps, _ in done) / max(seconds for _, seconds in done)


class _Timers:
    """Wraps functions so that every call adds its wall time to a named total."""

    def __init__(self):
        self.total, self.calls = collections.Counter(), collections.Counter()
        self._undo = []
        noop = self.wrap("noop", lambda: None)
        for _ in range(100_000):
            noop()
        self.overhead = self.total.pop("noop") / self.calls.pop("noop")

    def wrap(self, name, fn):
        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.total[name] += time.perf_counter() - start
                self.calls[name] += 1

        return timed

    def patch(self, owner, attr, name):
        original = getattr(owner, attr)
        self._undo.append((owner, attr, original))
        setattr(owner, attr, self.wrap(name, original))

    def restore(self):
        for owner, attr, original in reversed(self._undo):
            setattr(owner, attr, original)

    def net(self, name):
        """Seconds in `name`, less the timers' own cost."""
        return self.total[name] - self.calls[name] * self.overhead


def profile_parts(specs, params, config):
    """µs per env-step by part of one batch in this process, and the controller's batch."""
    timers = _Timers()
    batch = cpu_engine._Batch
    parts = [
        (mujoco, "mj_step1", "step1"),
        (mujoco, "mj_step2", "step2"),
        (batch, "_sense", "sense"),
        (batch, "_end_trials", "end"),
        (cpu_engine, "wrench_in_goal_frame", "wrench"),
        (cpu_engine, "skill_torque", "controller"),
    ]
    for owner, attr, name in parts:
        timers.patch(owner, attr, name)
    sense_in_end = [0.0]
    end = batch._end_trials

    def end_trials(self, n, source):  # the rows it refills are sensed inside it
        before = timers.total["sense"]
        try:
            return end(self, n, source)
        finally:
            sense_in_end[0] += timers.total["sense"] - before

    batch._end_trials = end_trials
    try:
        start = time.perf_counter()
        result = cpu_engine.run_trials(specs, params, config, workers=1)
        wall = time.perf_counter() - start
    finally:
        timers.restore()
    steps = int(result.steps.sum())
    net = {k: timers.net(k) for k in ("step1", "step2", "sense", "end", "wrench", "controller")}
    shares = {
        "mj_step1 + mj_step2 (physics)": net["step1"] + net["step2"],
        "per-trial sensing (jacobians, mass matrix, copies)": net["sense"] - net["step1"],
        "end checks, results, loading trials": net["end"] - sense_in_end[0],
        "wrench_in_goal_frame": net["wrench"],
        "skill_torque (controller)": net["controller"],
    }
    shares["the rest (torque writes, loop, Jd qd, peak force)"] = wall - sum(shares.values())
    calls = timers.calls["controller"]
    lines = [f"{k}: {1e6 * v / steps:.2f}" for k, v in shares.items()]
    lines.append(f"total: {1e6 * wall / steps:.2f} ({steps / wall:,.0f} steps/s)")
    lines.append(
        f"controller: {calls} calls, {steps / calls:.1f} trials per call on average, "
        f"{1e6 * net['controller'] / calls:.0f} µs per call"
    )
    return lines


def time_mjx(specs, params, config, batch):
    import jax

    from mjx_peg.engines import mjx as mjx_engine

    start = time.perf_counter()
    mjx_engine.run_trials(specs, params, config, batch=batch)  # compile + first run
    first = time.perf_counter() - start
    start = time.perf_counter()
    result = mjx_engine.run_trials(specs, params, config, batch=batch)
    elapsed = time.perf_counter() - start
    return result, elapsed, first - elapsed, jax.devices()[0].device_kind


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=200)
    p.add_argument("--workers", type=int, default=cpu_engine.available_cores())
    p.add_argument("--replay-every", type=int, default=50)
    p.add_argument("--time-limit", type=float, default=10.0, help="simulated s per trial")
    p.add_argument("--mjx-trials", type=int, default=8, help="0 skips the mjx engine")
    p.add_argument("--mjx-time-limit", type=float, default=2.0, help="simulated s (mjx)")
    p.add_argument("--repeat", type=int, default=2, help="engine runs per row (best kept)")
    p.add_argument("--no-profile", action="store_true", help="skip the per-part profile")
    p.add_argument("--write", action="store_true", help="update BENCHMARKS.md")
    args = p.parse_args()

    task = TaskConfig(shapes=("square",), linear_error=0.003, angular_error=np.deg2rad(4.0))
    config = TrialConfig(time_limit_s=args.time_limit)
    specs = sample_trials(task, 0, args.trials)
    params = as_controller_params(baseline_params(), len(specs))
    warm = specs.take(np.arange(4))
    cpu_engine.run_trials(warm, params, config, workers=1)  # warm-up
    start = time.perf_counter()
    cpu_engine.run_trials(warm, params, config, workers=args.workers)  # starts the pool
    first_call = time.perf_counter() - start

    snaps = record_states(specs, params, config, args.replay_every)
    rows, notes = [], [f"load average before: {os.getloadavg()[0]:.2f}"]
    for workers in sorted({1, args.workers}):
        # Best of three: one replay lasts about a second on this machine, which is noisy.
        ceiling = max(replay(specs, snaps, args.replay_every, workers) for _ in range(3))
        # Best of `--repeat` too: other jobs on a shared machine come and go.
        result, wall = min(
            (time_engine(specs, params, config, workers) for _ in range(args.repeat)),
            key=lambda run: run[1],
        )
        rate = int(result.steps.sum()) / wall
        slots = min(cpu_engine.SLOTS_PER_THREAD, -(-len(specs) // workers))
        rows.append(
            (
                "mujoco",
                cpu_name(),
                f"{len(specs)} ({slots} slots)",
                workers,
                "-",
                rate,
                len(specs) / wall,
                f"{100 * rate / ceiling:.0f} % of ceiling",
                result.summary(),
            )
        )
        replayed = f"{len(snaps)} snapshots x {args.replay_every} steps"
        rows.append(
            ("bare mj_step (ceiling)", cpu_name(), len(snaps), workers, "-", ceiling, "-", "",
             replayed)
        )  # fmt: skip
        overhead = call_overhead(specs, params, workers)
        notes.append(
            f"{workers} process(es): {1e3 * overhead:.1f} ms per call of 2 one-step trials"
        )
    notes.append(f"load average after: {os.getloadavg()[0]:.2f}")
    notes.append(f"first call on {args.workers} processes (starts them): {first_call:.2f} s")
    if not args.no_profile:
        notes += ["profile of one batch in this process, µs per env-step:"]
        notes += ["  " + line for line in profile_parts(specs, params, config)]
    if args.mjx_trials:
        sub = specs.take(np.arange(args.mjx_trials))
        sub_params = as_controller_params(baseline_params(), len(sub))
        mjx_config = TrialConfig(time_limit_s=args.mjx_time_limit)
        mres, mwall, compile_s, device = time_mjx(sub, sub_params, mjx_config, args.mjx_trials)
        mrate = mres.steps.sum() / mwall
        rows.append(
            (
                "mjx (JAX impl)",
                device,
                len(sub),
                "-",
                f"{compile_s:.0f} s",
                mrate,
                len(sub) / mwall,
                "",
                mres.summary(),
            )
        )
    header = (
        "| engine | device | trials (batch) | processes | compile | physics steps/s | "
        "trials/s | ratio | outcome |\n|---|---|---|---|---|---|---|---|---|"
    )
    lines = [header]
    for r in rows:
        cells = [
            f"{c:,.0f}"
            if isinstance(c, float) and c > 100
            else (f"{c:.2f}" if isinstance(c, float) else str(c))
            for c in r
        ]
        lines.append("| " + " | ".join(cells) + " |")
    table = "\n".join(lines)
    print(table)
    print("\n".join(notes))
    if args.write:
        section = (
            "## Trial engines\n\nBaseline parameters, square 50 mm, errors ±3 mm / ±4 deg, "
            f"{args.time_limit:g} s limit ({args.mjx_time_limit:g} s for mjx). Physics steps/s "
            "counts only steps of live trials; the ceiling replays the engine's own states with "
            "bare `mj_step` on as many processes. Command: `python benchmarks/trials.py --write` "
            f"(--trials {args.trials}, --workers {args.workers}, --mjx-trials {args.mjx_trials})."
            f"\n\n{table}\n\n"
        )
        write_section(ROOT / "BENCHMARKS.md", "## Trial engines", section)


if __name__ == "__main__":
    main()
