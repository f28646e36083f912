"""The CPU engine's lanes laid out over two cores, and why its physics costs more than a replay's.

    python benchmarks/layouts.py [--trials 1000] [--layouts "2x500,1x1000/2,2x256,1x512/2"]
        [--repeat 2] [--sims 256,512] [--touch-mb 0,1,2,4,8,16]

`benchmarks/trials.py`'s workload (the hand-tuned baseline, the paper's skill, square 50 mm,
+-3 mm / +-4 deg, 2 s, every failure to the limit), then:

1. the engine in each layout, `LANESxSLOTS[/C threads]`: LANES lanes as Python threads of this
   process, SLOTS rows each, each lane's batches stepping on that many C threads (default 1),
   with the engine's profile hook: steps/s, and lane-µs per env-step by stage
   (`lanes.PROFILE_STAGES`, summed over the lanes: with two lanes, what each stage costs the two
   cores together), `--repeat` times in turn (this host's speed moves between runs);
2. bare `Batch.step` on the engine's own states (`trials.record_states`: snapshots and the
   engine's torques of each step after them), one step per call, on one C thread over `--sims`
   simulations, with `--touch-mb` megabytes of other memory written between its steps (as the
   engine's control period does): µs per step. It shows how much of the caches a batch's
   physics needs, and what another pass's traffic between steps costs it.

Results: BENCHMARKS.md, "The engine's physics against a replay of its own trajectory".
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _report import cpu_name  # benchmarks/ is on sys.path when run
from trials import StageTimes, record_states, replay_batch

from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.errors import UsageError
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.search import skill_config
from mjx_peg.world.task import TaskConfig, sample_trials

WINDOW = 50  # steps replayed from each snapshot


def parse_layout(text: str) -> dict:
    """`LANESxSLOTS[/C threads]` as run_on_cpu's threads, slots_per_thread, batch_threads."""
    try:
        lanes_slots, _, nthread = text.partition("/")
        lanes, slots = (int(v) for v in lanes_slots.split("x"))
        return dict(threads=lanes, slots_per_thread=slots, batch_threads=int(nthread or 1))
    except ValueError:
        raise UsageError(f"a layout is LANESxSLOTS[/C threads], e.g. 2x500 or 1x1000/2, got "
                         f"{text!r}") from None  # fmt: skip


def run_layout(specs, params, config, layout: dict) -> str:
    """One profiled run of the engine in `layout`: its line of the table."""
    times = StageTimes()
    start = time.perf_counter()
    result = cpu_engine.run_on_cpu(specs, params, config, profile=times, **layout)
    wall = time.perf_counter() - start
    steps, periods = int(result.steps.sum()), times.calls["step"]
    lane_wall = layout["threads"] * wall
    stages = {k: 1e6 * v / steps for k, v in times.seconds.items()}
    stages["idle and the rest"] = 1e6 * (lane_wall - sum(times.seconds.values())) / steps
    text = ", ".join(f"{k} {v:.2f}" for k, v in stages.items())
    rows = steps / periods
    return (f"{steps / wall:,.0f} steps/s ({result.success.sum()} inserted), {rows:.0f} rows "
            f"per lane-period; lane-µs per env-step: {text}")  # fmt: skip


def batch_step_us(specs, snaps, nsim: int, touch_mb: float, chunks: int = 4) -> float:
    """µs per step of `Batch.step` (one C thread, `nsim` simulations, one step per call) on
    `chunks` x `nsim` snapshots with the engine's torques, `touch_mb` MB written between steps."""
    other = np.zeros(int(touch_mb * 2**20 / 8)) if touch_mb else None
    touch = None if other is None else lambda: np.add(other, 1.0, out=other)
    return 1e6 / replay_batch(specs, snaps[: chunks * nsim], WINDOW, 1, nsim=nsim, between=touch)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=1000)
    p.add_argument("--layouts", default="2x500,1x1000/2,2x256,1x512/2")
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--sims", default="256,512", help="simulations per batch (part 2)")
    p.add_argument("--touch-mb", default="0,1,2,4,8,16", help="MB written between steps")
    args = p.parse_args()
    layouts = {text: parse_layout(text) for text in args.layouts.split(",") if text}
    task = TaskConfig(shapes=("square",), linear_error=0.003, angular_error=np.deg2rad(4.0))
    config = TrialConfig(time_limit_s=2.0, end_settled=False, search=skill_config("paper"))
    specs = sample_trials(task, 0, args.trials)
    params = as_controller_params(baseline_params(), len(specs))
    warm = specs.take(np.arange(4))
    for layout in layouts.values():  # the compiled programs of each slot count
        cpu_engine.run_on_cpu(warm, as_controller_params(baseline_params(), 4), config, **layout)
    print(f"{cpu_name()}; {args.trials} trials, the compiled pass")
    for run in range(args.repeat):
        for text, layout in layouts.items():
            print(f"run {run + 1}, {text}: {run_layout(specs, params, config, layout)}", flush=True)
    nsims = [int(v) for v in args.sims.split(",") if v]
    touch = [float(v) for v in args.touch_mb.split(",") if v]
    if nsims and touch:
        snaps = record_states(specs, params, config, WINDOW)
        print(f"`Batch.step`, one C thread, µs per step, by MB written between steps "
              f"({len(snaps)} snapshots):")  # fmt: skip
        for run in range(args.repeat):
            for nsim in nsims:
                cells = " ".join(f"{mb:g} MB {batch_step_us(specs, snaps, nsim, mb):.2f}"
                                 for mb in touch)  # fmt: skip
                print(f"run {run + 1}, {nsim} simulations: {cells}", flush=True)


if __name__ == "__main__":
    main()
