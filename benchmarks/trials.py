"""Trial throughput of each engine, against the physics alone on the engine's own states.

    python benchmarks/trials.py [--trials 1000] [--threads N] [--passes numpy,compiled]
        [--shapes square] [--skill paper] [--mjx-trials 8] [--write]

Runs the hand-tuned baseline on `--trials` 50 mm trials (`--shapes`, `--skill`) at 3 mm / 4 deg
on the mujoco engine with 1 lane and with `--threads` lanes (default: every core) as threads of
this process and as worker processes, with each control-period pass of `--passes` (the NumPy
pass, the compiled one: `run_on_cpu(compiled=...)`), every failure to the time limit, and reports
physics steps/s and trials/s. In the same run, two references: the states the engine visited (a
snapshot every `--replay-every` steps, contacts included, and the torques the engine applied in each
step after it) replayed with plain `mj_step` and those torques, no controller, on as many processes
as lanes (the ceiling; its timing holds a NumPy write of `ctrl` per step), and the same snapshots
stepped by `mujoco.batch.Batch`, one step per call over 512 simulations at a time (the physics as
the engine runs it, on the engine's own trajectory: each window ends on the engine's next snapshot
bit for bit, counted in the notes; the engine's ratio to it is the share of the wall time that is
physics; every engine run is paired with a `Batch.step` run just before it, and the row gives each
pair's ratio and their median). Beside them, `Batch.step` with each snapshot's torques held through
its window (the reference until 2026-12-07: its states leave the engine's). Then the engine with
early ending (TrialConfig.end_settled, the default), the fixed cost of a call, and a profile of one
lane by stage for each pass (the engine's `profile` hook, `lanes.PROFILE_STAGES`). The mjx engine is
timed on `--mjx-trials` trials (compile time reported apart). `--write` replaces the "## Trial
engines" section of BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import collections
import functools
import multiprocessing
import os
import threading
import time

import mujoco
import mujoco.batch
import numpy as np
from _report import ROOT, cpu_name, write_section  # benchmarks/ is on sys.path when run

from mjx_peg.cores import cores
from mjx_peg.engines import lanes, sims
from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.search import SKILLS, skill_config
from mjx_peg.world import scene
from mjx_peg.world.task import TaskConfig, sample_trials

STATE = mujoco.mjtState.mjSTATE_INTEGRATION


def time_engine(specs, params, config, threads, compiled, processes=None):
    """(result, wall s, CPU s of this process: all its threads)."""
    start, cpu = time.perf_counter(), time.process_time()
    result = cpu_engine.run_on_cpu(specs, params, config, threads=threads, compiled=compiled,
                                   processes=processes)  # fmt: skip
    return result, time.perf_counter() - start, time.process_time() - cpu


def call_overhead(specs, params, threads, compiled, calls=20):
    """Median wall time (s) of a call running 2 trials of one step each."""
    config = TrialConfig(time_limit_s=TrialConfig().timestep)
    two, times = specs.take(np.arange(2)), []
    cpu_engine.run_on_cpu(two, params, config, threads=threads, compiled=compiled)  # compiles
    for _ in range(calls):
        start = time.perf_counter()
        cpu_engine.run_on_cpu(two, params, config, threads=threads, compiled=compiled)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def trial_model(specs, index):
    """The model of trial `index`: its scene with its board pose, grasp and friction."""
    m = scene.load_model(*sims.scene_key(specs, index))
    scene.start_trial(specs, index, m, mujoco.MjData(m), scene.scene_ids(m))
    return m


def record_states(specs, params, config, every):
    """(spec index, state, torques) snapshots of the engine's trials, every `every` steps: the
    integration state before a step and the (every, 6) torques the engine applied in the `every`
    steps from it (a window a trial does not live through is dropped)."""
    snaps, windows = [], {}

    def observe(lane, rows, wrench):
        # Each live row's ctrl holds the torques of its previous step.
        blocks = [(k, ids) for k, (a, b, ids) in enumerate(lane.blocks) if b > a]
        ctrl = np.concatenate([lane.scenes[k].ctrl[ids] for k, ids in blocks])
        row_of = {int(s): i for i, s in enumerate(lane.spec_index)}
        for index in list(windows):
            state, torques = windows[index]
            row = row_of.get(index)
            if row is None:
                del windows[index]  # the trial ended inside the window
                continue
            torques.append(ctrl[row].copy())
            if len(torques) == every:
                snaps.append((index, state, np.array(torques)))
                del windows[index]
        for i in rows[lane.step[rows] % every == 0]:
            m, d, _ = lane.current[i]
            state = np.empty(mujoco.mj_stateSize(m, STATE))
            mujoco.mj_getState(m, d, state, STATE)
            windows[int(lane.spec_index[i])] = (state, [])

    cpu_engine.run_on_cpu(specs, params, config, threads=1, observer=observe)
    return snaps


def _replay_part(specs, snaps, every, barrier, held):
    """Steps/s of bare mj_step from each snapshot for `every` steps, the engine's torques of
    each step or (`held`) the snapshot's held (run in a worker process)."""
    models, jobs = {}, []
    for index, state, torques in snaps:
        if index not in models:
            m = trial_model(specs, index)
            models[index] = (m, mujoco.MjData(m))
        jobs.append((*models[index], state, torques))
    barrier.wait()
    start, cpu = time.perf_counter(), time.process_time()
    for m, d, state, torques in jobs:
        mujoco.mj_setState(m, d, state, STATE)
        for k in range(every):
            if not held:
                d.ctrl[:] = torques[k]
            mujoco.mj_step(m, d)
    return len(jobs) * every, time.perf_counter() - start, time.process_time() - cpu


def replay(specs, snaps, every, processes, held=False):
    """Bare mj_step from every snapshot on `processes` processes started together: steps/s, and
    CPU s per step."""
    ctx = multiprocessing.get_context("spawn")
    with ctx.Manager() as manager, ctx.Pool(processes) as pool:
        barrier = manager.Barrier(processes)
        parts = [(specs, snaps[k::processes], every, barrier, held) for k in range(processes)]
        done = pool.starmap(_replay_part, parts)
    steps = sum(s for s, _, _ in done)
    return steps / max(w for _, w, _ in done), sum(c for _, _, c in done) / steps


def replay_batch(specs, snaps, every, nthread, nsim=512, held=False, check=None, between=None):
    """The snapshots stepped by one persistent mujoco.batch.Batch per scene, `nsim` at a time,
    one step per call (as the engine steps) with the engine's torques of each step (or, `held`,
    the snapshot's held); steps/s of the step calls. `check`: a list that gets, per snapshot
    whose trial has a snapshot `every` steps later, whether the replay ends on it bit for bit.
    `between()`, if given, runs before each step, outside the timing."""
    by_scene = collections.defaultdict(list)
    for snap in snaps:
        by_scene[sims.scene_key(specs, snap[0])].append(snap)

    def step_of(state):
        return int(round(state[0] / TrialConfig().timestep))  # a state's first number: its time

    later = {} if check is None else {(i, step_of(state)): state for i, state, _ in snaps}
    steps, seconds = 0, 0.0
    for key, jobs in by_scene.items():
        batch = sims.Sims(key, min(nsim, len(jobs)), nthread)
        for start in range(0, len(jobs), batch.nsim):
            chunk = jobs[start : start + batch.nsim]
            for sim, (index, state, _) in enumerate(chunk):
                batch.load(sim, specs, index)  # the trial's model fields
                batch.state[sim] = state
            ids = np.arange(len(chunk), dtype=np.int32)
            torques = np.stack([t for _, _, t in chunk], axis=1)  # (every, sims, 6)
            batch.forward(ids)
            for k in range(every):
                if not held:
                    batch.ctrl[ids] = torques[k]
                if between is not None:
                    between()
                begin = time.perf_counter()
                batch.batch.step(ids, stage=sims.STAGE_VEL)
                seconds += time.perf_counter() - begin
            steps += len(chunk) * every
            for sim, (index, state, _) in enumerate(chunk):
                end = later.get((index, step_of(state) + every))
                if end is not None:
                    check.append(bool(np.array_equal(batch.state[sim], end)))
    return steps / seconds


def paired_run(specs, snaps, every, threads, run):
    """(run(), steps/s of bare `Batch.step` on the snapshots, timed just before it)."""
    reference = replay_batch(specs, snaps, every, threads)
    return run(), reference


class StageTimes:
    """A profile hook for the CPU engine: seconds and calls per stage, summed over its lanes
    (lanes in several threads call it at once)."""

    def __init__(self):
        self.seconds, self.calls = collections.Counter(), collections.Counter()
        self._lock = threading.Lock()

    def __call__(self, stage: str, seconds: float) -> None:
        with self._lock:
            self.seconds[stage] += seconds
            self.calls[stage] += 1


def profile_parts(specs, params, config, compiled, unprofiled_wall=None, slots=None):
    """µs per env-step by stage of one lane of `slots` (None: the engine's) in this process
    (`run_on_cpu(profile=...)`)."""
    times = StageTimes()
    start = time.perf_counter()
    result = cpu_engine.run_on_cpu(specs, params, config, threads=1, profile=times,
                                   compiled=compiled, slots_per_thread=slots)  # fmt: skip
    wall = time.perf_counter() - start
    steps, periods = int(result.steps.sum()), times.calls["step"]
    shares = {f"{name}: {text}": times.seconds[name] for name, text in lanes.PROFILE_STAGES.items()}
    shares["the rest: the queue, progress, the lane's loop"] = wall - sum(shares.values())
    lines = [f"{k}: {1e6 * v / steps:.2f}" for k, v in shares.items()]
    lines.append(f"total: {1e6 * wall / steps:.2f} ({steps / wall:,.0f} steps/s)")
    if unprofiled_wall:
        lines.append(f"the table's 1-thread run (no hook, best of --repeat): "
                     f"{1e6 * unprofiled_wall / steps:.2f}")  # fmt: skip
    per_period = 1e6 / max(periods, 1)  # s -> µs per period
    control_pass = wall - times.seconds["step"] - times.seconds["load"]
    lines.append(
        f"{periods} control periods, {steps / max(periods, 1):.1f} trials each on average; "
        f"`period.advance` {per_period * times.seconds['advance']:.0f} µs per period, the "
        f"pass (all but the physics and loads) {per_period * control_pass:.0f} µs, "
        f"{100 * control_pass / wall:.0f} % of the wall time"
    )
    return lines


def time_mjx(specs, params, config, batch):
    import jax

    from mjx_peg.engines import mjx as mjx_engine

    start = time.perf_counter()
    mjx_engine.run_on_device(specs, params, config, batch=batch)  # compile + first run
    first = time.perf_counter() - start
    start = time.perf_counter()
    result = mjx_engine.run_on_device(specs, params, config, batch=batch)
    elapsed = time.perf_counter() - start
    return result, elapsed, first - elapsed, jax.devices()[0].device_kind


def _commit() -> str:
    """The checkout's short commit, '+' where its tracked files differ from it."""
    import subprocess

    def git(*argv):
        return subprocess.run(["git", *argv], cwd=ROOT, capture_output=True, text=True).stdout

    head = git("rev-parse", "--short", "HEAD").strip() or "unknown"
    return head + ("+" if git("status", "--porcelain", "--untracked-files=no").strip() else "")


def _row(*cells):
    out = []
    for c in cells:
        if isinstance(c, float):
            out.append(f"{c:,.0f}" if c > 100 else f"{c:.2f}")
        else:
            out.append(str(c))
    return "| " + " | ".join(out) + " |"


PASSES = {"numpy": False, "compiled": True}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=1000)
    p.add_argument("--threads", type=int, default=cores(), help="lanes of the many-lane rows")
    p.add_argument("--passes", default="numpy,compiled", help="control-period passes to time")
    p.add_argument("--shapes", default="square", help="comma-separated, 50 mm")
    p.add_argument("--skill", default="paper", choices=tuple(SKILLS))
    p.add_argument("--replay-every", type=int, default=50)
    p.add_argument("--time-limit", type=float, default=10.0, help="simulated s per trial")
    p.add_argument("--mjx-trials", type=int, default=8, help="0 skips the mjx engine")
    p.add_argument("--mjx-time-limit", type=float, default=2.0, help="simulated s (mjx)")
    p.add_argument("--repeat", type=int, default=2, help="engine runs per row (best kept)")
    p.add_argument("--no-profile", action="store_true", help="skip the per-stage profile")
    p.add_argument("--write", action="store_true", help="update BENCHMARKS.md")
    args = p.parse_args()
    passes = [name.strip() for name in args.passes.split(",")]
    if not passes or any(name not in PASSES for name in passes):
        p.error(f"--passes: names among {', '.join(PASSES)}")

    task = TaskConfig(shapes=tuple(args.shapes.split(",")), linear_error=0.003,
                      angular_error=np.deg2rad(4.0))  # fmt: skip
    full = TrialConfig(time_limit_s=args.time_limit, end_settled=False,
                       search=skill_config(args.skill))  # fmt: skip
    specs = sample_trials(task, 0, args.trials)
    params = as_controller_params(baseline_params(), len(specs))
    warm = specs.take(np.arange(4))
    for name in passes:  # warm-up: the compiled programs of every config and slot count below
        for threads in sorted({1, args.threads}):
            for config in (full, full.replace(end_settled=True)):
                cpu_engine.run_on_cpu(warm, params, config, threads=threads,
                                      compiled=PASSES[name],
                                      slots_per_thread=-(-len(specs) // threads))  # fmt: skip
        cpu_engine.run_on_cpu(warm, params, full, processes=args.threads, compiled=PASSES[name],
                              slots_per_thread=-(-len(specs) // args.threads))  # fmt: skip

    snaps = record_states(specs, params, full, args.replay_every)
    replayed = f"{len(snaps)} snapshots x {args.replay_every} steps"
    rows, notes = [], [f"load average before: {os.getloadavg()[0]:.2f}"]
    walls = {}
    for threads in sorted({1, args.threads}):
        # Best of three: one replay lasts about a second on this machine, which is noisy.
        ceiling, ceiling_cpu = max(
            replay(specs, snaps, args.replay_every, threads) for _ in range(3)
        )
        check = []
        in_batch = max(replay_batch(specs, snaps, args.replay_every, threads, check=check)
                       for _ in range(2))  # fmt: skip
        held = max(replay_batch(specs, snaps, args.replay_every, threads, held=True)
                   for _ in range(2))  # fmt: skip
        bare = f"CPU {1e6 * ceiling_cpu:.2f} µs/step"
        rows.append(_row("bare mj_step (ceiling)", cpu_name(), len(snaps), f"{threads} processes",
                         ceiling, "-", bare, replayed))  # fmt: skip
        rows.append(_row("bare `Batch.step`", cpu_name(), len(snaps), threads, in_batch, "-",
                         f"{100 * in_batch / ceiling:.0f} % of ceiling",
                         f"{replayed}, 512 simulations per batch, one step per call"))  # fmt: skip
        rows.append(_row("bare `Batch.step`, each snapshot's torques held", cpu_name(),
                         len(snaps), threads, held, "-", f"{100 * held / ceiling:.0f} % of ceiling",
                         "states that leave the engine's within the window"))  # fmt: skip
        notes.append(f"{threads} thread(s): the `Batch.step` replay ends on the engine's next "
                     f"snapshot bit for bit in {sum(check)} of {len(check)} windows")  # fmt: skip
        lanes_as = [("threads", None)] + ([("processes", threads)] if threads > 1 else [])
        for name in passes:
            for how, processes in lanes_as:
                # `--repeat` runs, each paired with `Batch.step` timed just before it (this
                # host's speed moves between runs by more than the engines differ); the rate is
                # the fastest run's, the share of physics the median pair's.
                engine = functools.partial(time_engine, specs, params, full,
                                           None if processes else threads, PASSES[name],
                                           processes)  # fmt: skip
                pairs = [paired_run(specs, snaps, args.replay_every, threads, engine)
                         for _ in range(args.repeat)]  # fmt: skip
                result, wall, cpu = min((run for run, _ in pairs), key=lambda run: run[1])
                shares = [int(run[0].steps.sum()) / run[1] / ref for run, ref in pairs]
                steps = int(result.steps.sum())
                rate, cpu_step = steps / wall, cpu / steps
                walls[(name, threads, how)] = wall
                slots = min(lanes.SLOTS_PER_THREAD, -(-len(specs) // threads))
                cpu_text = f"; CPU {1e6 * cpu_step:.2f} µs/step" if how == "threads" else ""
                each = " / ".join(f"{100 * x:.0f}" for x in shares)
                ratio = (f"**{100 * float(np.median(shares)):.0f} %** of `Batch.step` (pairs: "
                         f"{each} %), {100 * rate / ceiling:.0f} % of ceiling"
                         f"{cpu_text}")  # fmt: skip
                batch = f"{len(specs)} ({slots} per lane)"
                label = f"mujoco, {name} pass, lanes as {how}"
                rows.append(_row(label, cpu_name(), batch, threads, rate, len(specs) / wall,
                                 ratio, result.summary()))  # fmt: skip
            overhead = call_overhead(specs, params, threads, PASSES[name])
            notes.append(f"{name} pass, {threads} lane(s): {1e3 * overhead:.1f} ms per call of "
                         f"2 one-step trials")  # fmt: skip
    for name in passes:
        early, wall, _ = time_engine(specs, params, full.replace(end_settled=True), args.threads,
                                     PASSES[name])  # fmt: skip
        rate = int(early.steps.sum()) / wall
        rows.append(_row(f"mujoco, {name} pass, early ending", cpu_name(), f"{len(specs)}",
                         args.threads, rate, len(specs) / wall,
                         f"{100 * rate / ceiling:.0f} % of ceiling", early.summary()))  # fmt: skip
    notes.append(f"load average after: {os.getloadavg()[0]:.2f}")
    if not args.no_profile:
        for name in passes:
            notes += [f"profile of one lane (threads=1), {name} pass, µs per env-step:"]
            notes += ["  " + line for line in profile_parts(
                specs, params, full, PASSES[name], walls[(name, 1, "threads")])]  # fmt: skip
    if args.mjx_trials:
        sub = specs.take(np.arange(args.mjx_trials))
        sub_params = as_controller_params(baseline_params(), len(sub))
        mjx_config = TrialConfig(time_limit_s=args.mjx_time_limit, search=full.search)
        mres, mwall, compile_s, device = time_mjx(sub, sub_params, mjx_config, args.mjx_trials)
        rows.append(
            _row("mjx (JAX impl)", device, len(sub), "-", mres.steps.sum() / mwall,
                 len(sub) / mwall, f"compile {compile_s:.0f} s", mres.summary())
        )  # fmt: skip
    header = (
        "| engine | device | trials (batch) | lanes | physics steps/s | trials/s | ratio | "
        "outcome |\n|---|---|---|---|---|---|---|---|"
    )
    table = "\n".join([header, *rows])
    print(table)
    print("\n".join(notes))
    if args.write:
        mjx = f" ({args.mjx_time_limit:g} s for mjx)" if args.mjx_trials else ""
        section = (
            f"## Trial engines\n\nMeasured {time.strftime('%Y-%m-%d')} at commit {_commit()}. "
            f"Baseline parameters, the {args.skill} skill, {args.shapes} 50 mm, errors ±3 mm / "
            f"±4 deg, {args.time_limit:g} s limit{mjx}. Physics steps/s counts only steps of live "
            "trials; the ceiling replays the engine's own trajectory (its snapshots and the "
            "torques it applied at each step after them) with bare `mj_step` on as many "
            "processes. Each engine run is timed right after bare `Batch.step` on the same "
            "trajectory; the ratio gives each pair's share and their median in bold. Command: "
            "`python benchmarks/trials.py --write` (--trials "
            f"{args.trials}, --threads {args.threads}, --time-limit {args.time_limit:g}, "
            f"--repeat {args.repeat}, --mjx-trials {args.mjx_trials}).\n\n{table}\n\n"
            + "\n".join(f"- {note}" for note in notes if not note.startswith((" ", "profile")))
            + "\n\n"
        )
        write_section(ROOT / "BENCHMARKS.md", "## Trial engines", section)


if __name__ == "__main__":
    main()
