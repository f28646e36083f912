"""Trial throughput of each engine, against the raw ceiling of bare mj_step on the same scene.

    python benchmarks/trials.py [--trials 200] [--threads N] [--mjx-trials 16] [--write]

Runs the hand-tuned baseline on `--trials` square 50 mm trials at 3 mm / 4 deg on the mujoco
engine and reports physics steps/s and trials/s. In the same run, the ceiling: the states the
engine visited (a snapshot every `--replay-every` steps, contacts included) are replayed with
plain `mj_step` and the recorded torques held, across the same number of threads, no controller.
The mjx engine is timed on `--mjx-trials` trials (compile time reported apart). `--write`
replaces the "## Trial engines" section of BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import copy
import threading
import time

import mujoco
import numpy as np
from _report import ROOT, cpu_name, write_section  # benchmarks/ is on sys.path when run

from mjx_peg import scene
from mjx_peg.baseline import baseline_params
from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.task import TaskConfig, sample_trials
from mjx_peg.trial import TrialConfig, as_controller_params


def time_engine(specs, params, config, threads):
    start = time.perf_counter()
    result = cpu_engine.run_trials(specs, params, config, threads=threads)
    return result, time.perf_counter() - start


def record_states(specs, params, config, every):
    """(model key, state, ctrl, steps) snapshots of the engine's trials, every `every` steps."""
    snaps = []
    lock = threading.Lock()

    def observe(worker, rows, wrench):
        for i in rows:
            if worker.step[i] % every == 0:
                m, d, _ = worker.current[i]
                state = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION))
                mujoco.mj_getState(m, d, state, mujoco.mjtState.mjSTATE_INTEGRATION)
                with lock:
                    snaps.append((worker.spec_index[i], state))

    cpu_engine.run_trials(specs, params, config, threads=1, observer=observe)
    return snaps


def replay(specs, snaps, every, threads):
    """Bare mj_step from each snapshot for `every` steps on `threads` threads; steps/s."""
    chunks = [snaps[i::threads] for i in range(threads)]

    def prepare(chunk):
        envs = {}
        jobs = []
        for index, state in chunk:
            shape = scene.SHAPES[int(specs.shape_id[index])]
            key = (shape, float(specs.size[index]))
            if key not in envs:
                m = copy.deepcopy(scene.load_model(*key))
                envs[key] = (m, mujoco.MjData(m))
            m, d = envs[key]
            jobs.append((m, d, index, state))
        return jobs

    prepared = [prepare(c) for c in chunks]

    def work(jobs):
        for m, d, index, state in jobs:
            scene.set_board_pose(m, *specs.board_pos[index], specs.board_yaw[index])
            scene.set_grasp(m, *specs.grasp_error[index])
            scene.set_friction(m, specs.friction[index])
            mujoco.mj_setState(m, d, state, mujoco.mjtState.mjSTATE_INTEGRATION)
            for _ in range(every):
                mujoco.mj_step(m, d)

    pool = [threading.Thread(target=work, args=(jobs,)) for jobs in prepared]
    start = time.perf_counter()
    for t in pool:
        t.start()
    for t in pool:
        t.join()
    elapsed = time.perf_counter() - start
    return len(snaps) * every / elapsed


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
    p.add_argument("--threads", type=int, default=cpu_engine.available_cores())
    p.add_argument("--replay-every", type=int, default=50)
    p.add_argument("--time-limit", type=float, default=10.0, help="simulated s per trial")
    p.add_argument("--mjx-trials", type=int, default=8, help="0 skips the mjx engine")
    p.add_argument("--mjx-time-limit", type=float, default=2.0, help="simulated s (mjx)")
    p.add_argument("--write", action="store_true", help="update BENCHMARKS.md")
    args = p.parse_args()

    task = TaskConfig(shapes=("square",), linear_error=0.003, angular_error=np.deg2rad(4.0))
    config = TrialConfig(time_limit_s=args.time_limit)
    specs = sample_trials(task, 0, args.trials)
    params = as_controller_params(baseline_params(), len(specs))
    cpu_engine.run_trials(specs.take(np.arange(4)), params, config, threads=1)  # warm-up

    snaps = record_states(specs, params, config, args.replay_every)
    rows = []
    for threads in sorted({1, args.threads}):
        # Best of three: one replay lasts about a second on this machine, which is noisy.
        ceiling = max(replay(specs, snaps, args.replay_every, threads) for _ in range(3))
        result, wall = time_engine(specs, params, config, threads)
        rate = int(result.steps.sum()) / wall
        ratio = f"{100 * rate / ceiling:.0f} % of ceiling"
        rows.append(
            (
                "mujoco",
                cpu_name(),
                len(specs),
                threads,
                "-",
                rate,
                len(specs) / wall,
                ratio,
                result.summary(),
            )
        )
        replayed = f"{len(snaps)} snapshots x {args.replay_every} steps"
        rows.append(
            (
                "bare mj_step (ceiling)",
                cpu_name(),
                len(snaps),
                threads,
                "-",
                ceiling,
                "-",
                "",
                replayed,
            )
        )
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
        "| engine | device | trials (batch) | threads | compile | physics steps/s | "
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
    if args.write:
        section = (
            "## Trial engines\n\nBaseline parameters, square 50 mm, errors ±3 mm / ±4 deg, "
            f"{args.time_limit:g} s limit ({args.mjx_time_limit:g} s for mjx). Physics steps/s "
            "counts only steps of live trials. Command: `python benchmarks/trials.py --write` "
            f"(--trials {args.trials}, --threads {args.threads}, --mjx-trials {args.mjx_trials})."
            f"\n\n{table}\n"
        )
        write_section(ROOT / "BENCHMARKS.md", "## Trial engines", section)


if __name__ == "__main__":
    main()
