"""What a physics step costs on the shipped skill's states, and why the engine pays more for it.

    python benchmarks/physics.py [--trials 120] [--linear-mm 8] [--angular-deg 12]
        [--every 200] [--sims 16,32,64,128,256,512]

Records the states of `--trials` trials of the spiral skill with the hand-tuned controller
(circle and square 50 mm at the paper's training errors, 20 s; a snapshot every `--every` steps,
contacts included), then on one core:

1. bare `mj_step` from each snapshot (10 steps, one MjData hot in the caches), by part and by the
   number of contacts: the physics' own cost and how contact raises it;
2. the same steps under MuJoCo's stage timers (`mjcb_time`): which stage of `mj_step` takes it
   (the timers add their own cost; their shares are what counts);
3. `mujoco.batch.Batch.step` over the same snapshots, `--sims` simulations per batch, one step per
   call (as the engine steps): what walking many simulations per step costs against one hot one;
4. with `--slots`, the engine itself (one lane in this process, the compiled period) on
   `benchmarks/trials.py`'s workload (the paper skill, square, +-3 mm / +-4 deg, 2 s, every
   failure to the limit, `--slot-trials` trials) at each slot count per lane: the per-row
   physics that grows with the slots against the per-period cost that shrinks with them.
"""

from __future__ import annotations

import argparse
import functools
import time

import mujoco
import numpy as np
from _report import cpu_name  # benchmarks/ is on sys.path when run
from trials import record_states, replay_batch, trial_model

from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines.sims import STATE
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.search import skill_config
from mjx_peg.world.constants import SHAPES
from mjx_peg.world.task import TaskConfig, sample_trials

CONTACT_BINS = ((0, 0), (1, 4), (5, 8), (9, 1000))


def bare_steps(specs, snaps, steps: int = 10, change=None):
    """(contacts, µs per step) of `steps` bare mj_step calls from each snapshot; `change(model)`,
    if given, edits each trial's model (its options) before its first step."""
    models = {}
    rows = []
    for index, state, _ in snaps:
        if index not in models:
            m = trial_model(specs, index)
            if change is not None:
                change(m)
            models[index] = (m, mujoco.MjData(m))
        m, d = models[index]
        mujoco.mj_setState(m, d, state, STATE)
        mujoco.mj_step(m, d)  # the contacts of the state as it steps
        contacts = d.ncon
        start = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(m, d)
        rows.append((contacts, 1e6 * (time.perf_counter() - start) / steps))
    return np.array(rows), models


def stage_times(snaps, models, steps: int = 10) -> dict[str, float]:
    """µs per step of each of MuJoCo's timers over the snapshots (timers on)."""
    total = None
    mujoco.set_mjcb_time(lambda: time.perf_counter() * 1e6)
    try:
        for index, state, _ in snaps:
            m, d = models[index]
            mujoco.mj_setState(m, d, state, STATE)
            for timer in d.timer:
                timer.duration, timer.number = 0.0, 0
            for _ in range(steps):
                mujoco.mj_step(m, d)
            durations = np.array([timer.duration for timer in d.timer])
            total = durations if total is None else total + durations
    finally:
        mujoco.set_mjcb_time(None)
    per_step = total / (steps * len(snaps))
    names = (mujoco.mjtTimer(i).name.removeprefix("mjTIMER_") for i in range(len(total)))
    return dict(zip(names, per_step, strict=True))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=120)
    p.add_argument("--linear-mm", type=float, default=8.0)
    p.add_argument("--angular-deg", type=float, default=12.0)
    p.add_argument("--every", type=int, default=200, help="steps between snapshots")
    p.add_argument("--sims", default="16,32,64,128,256,512", help="simulations per batch")
    p.add_argument("--slots", default="", help="slot counts per lane for the engine, e.g. 64,512")
    p.add_argument("--slot-trials", type=int, default=1000)
    args = p.parse_args()
    task = TaskConfig(shapes=("circle", "square"), linear_error=args.linear_mm / 1000,
                      angular_error=np.deg2rad(args.angular_deg))  # fmt: skip
    config = TrialConfig(time_limit_s=20.0, search=skill_config("spiral"))
    specs = sample_trials(task, 0, args.trials)
    params = as_controller_params(baseline_params(), len(specs))
    snaps = record_states(specs, params, config, args.every)
    print(f"{cpu_name()}; {len(snaps)} snapshots of {args.trials} trials (spiral, hand-tuned, "
          f"+-{args.linear_mm:g} mm / +-{args.angular_deg:g} deg, 20 s), one core")  # fmt: skip
    rows, models = bare_steps(specs, snaps)
    contacts, micros = rows[:, 0], rows[:, 1]
    print(f"\nbare mj_step: {micros.mean():.1f} µs per step, {contacts.mean():.1f} contacts")
    shape = np.asarray(specs.shape_id)[[index for index, _, _ in snaps]]
    for k in np.unique(shape):
        on = shape == k
        print(f"  {SHAPES[k]}: {micros[on].mean():.1f} µs per step, "
              f"{contacts[on].mean():.1f} contacts, {on.sum()} states")  # fmt: skip
    print("| contacts | states | µs per step | share of the time |\n|---|---|---|---|")
    for low, high in CONTACT_BINS:
        on = (contacts >= low) & (contacts <= high)
        if on.any():
            span = f"{low}" if low == high else f"{low}-{high}" if high < 1000 else f"{low}+"
            print(f"| {span} | {100 * on.mean():.0f} % | {micros[on].mean():.1f} | "
                  f"{100 * micros[on].sum() / micros.sum():.0f} % |")  # fmt: skip
    stages = stage_times(snaps, models)
    print("\nMuJoCo's stage timers (timers on), µs per step:")
    print("| stage | µs | share of STEP |\n|---|---|---|")
    for name, value in stages.items():
        if value > 0:
            print(f"| {name} | {value:.2f} | {100 * value / stages['STEP']:.0f} % |")
    ceiling = len(snaps) * 10 / (micros.sum() * 10 / 1e6)
    print("\n`Batch.step`, one step per call, against bare mj_step's steps/s on the same states:")
    print("| simulations per batch | steps/s | of bare mj_step |\n|---|---|---|")
    for nsim in (int(s) for s in args.sims.split(",")):
        rate = max(replay_batch(specs, snaps, 10, 1, nsim=nsim) for _ in range(2))
        print(f"| {nsim} | {rate:,.0f} | {100 * rate / ceiling:.0f} % |")
    if args.slots:
        engine_by_slots([int(s) for s in args.slots.split(",")], args.slot_trials)


def engine_by_slots(slot_counts, trials: int) -> None:
    """Steps/s of the engine (one lane, this process; best of two runs) per slot count."""
    task = TaskConfig(shapes=("square",), linear_error=0.003, angular_error=np.deg2rad(4.0))
    config = TrialConfig(time_limit_s=2.0, end_settled=False, search=skill_config("paper"))
    specs = sample_trials(task, 0, trials)
    params = as_controller_params(baseline_params(), len(specs))
    print(f"\nthe engine, one lane, {trials} trials (paper skill, +-3 mm / +-4 deg, 2 s):")
    print("| slots per lane | steps/s |\n|---|---|")
    for slots in slot_counts:
        run = functools.partial(cpu_engine.run_on_cpu, params=params, config=config, threads=1,
                                slots_per_thread=slots)  # fmt: skip
        run(specs.take(np.arange(4)))  # compiles this slot count's programs
        best = 0.0
        for _ in range(2):
            start = time.perf_counter()
            steps = int(run(specs).steps.sum())
            best = max(best, steps / (time.perf_counter() - start))
        print(f"| {slots} | {best:,.0f} |")


if __name__ == "__main__":
    main()
