"""The CPU engine: C MuJoCo stepped by its own thread pool (`mujoco.batch`), the trial's periods
batched in NumPy over every live trial at once (`engines/lanes.py`, `engines/period.py`).

`run_on_cpu` runs the trials in lanes of this process (`threaded.run_in_threads`), in
worker processes (`processes.run_in_processes`) or on a Ray cluster (`ray_pool.run_on_cluster`);
all three give the same results, bit for bit (the compiled pass: but for the last bits of the
few trials that sit in the last slots of a program, docs/design/compiled_period.md).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mjx_peg.engines import lanes, threaded
from mjx_peg.engines.trial import TrialConfig, TrialResult
from mjx_peg.errors import UsageError
from mjx_peg.skill.params import ControllerParams
from mjx_peg.world.task import TrialSpec


def run_on_cpu(
    specs: TrialSpec,
    params: ControllerParams,
    config: TrialConfig,
    threads: int | None = None,
    slots_per_thread: int | None = None,
    progress: Callable[[int], None] | None = None,
    observer: Callable | None = None,
    batch_threads: int | None = None,
    persistent: bool | None = None,
    processes: int | None = None,
    ray: str | None = None,
    profile: Callable[[str, float], None] | None = None,
    compiled: bool | None = None,
) -> TrialResult:
    """Run every trial of `specs` with per-trial `params` (batched, validated) on C MuJoCo.

    threads: lanes, each a Python thread with its own batches (default: every core this process
    may use, at most one per trial).
    slots_per_thread: rows per lane (default: SLOTS_PER_THREAD, or fewer to spread the trials
    over every lane). batch_threads: C threads of each lane's batches (default 1).
    persistent: one MjData per simulation (`mujoco.batch.Batch(persistent=True)`: each step
    continues from the position and velocity stages the controller read) or one per C thread
    (a step recomputes them, but its memory stays in the cache); the same results. Default:
    persistent for batches of up to PERSISTENT_MAX_SIMS simulations.
    progress(count) is called in the caller's thread as trials finish. observer(lane, rows,
    wrench), if given, is called every control period with a lane, its live rows and their
    wrenches (for demos and benchmarks); it needs threads=1, its default then.
    profile(stage, seconds), if given, is called in the lane's thread as each stage of a period
    ends (`lanes.PROFILE_STAGES`: the physics step, the end tests, the Jacobians, ...; wall time),
    for benchmarks; the results are the same with it. It needs the lanes in this process.
    processes: run the trials in that many worker processes (`engines/processes.py`: one GIL
    each) of `threads` lanes each (default 1); None (the default): lanes in this process.
    ray: run them on the Ray cluster at this address, one lane per CPU (`engines/ray_pool.py`:
    "auto", "local" or HOST:PORT); the same results.
    compiled: each lane's control period compiled by XLA (`engines/compiled.py`: the same
    functions, float64, in XLA's order of operations) or the NumPy pass (the reference, and the
    robot's); default: compiled, unless the environment variable MJX_PEG_CONTROL_PASS says
    numpy. The NumPy pass gives the same results whatever the lanes, slots, processes or
    cluster; the compiled pass too, but for a trial in one of the last four slots of a program,
    whose few operations round otherwise (the same layout, the same bits; another layout can move
    a chaotic trial; lanes as threads of one process share one queue, so their layout follows the
    threads' timing: docs/design/compiled_period.md, "A trial's last bits and its slot"); the two
    agree to rounding, which contact can grow into a different trajectory (BENCHMARKS.md, "The
    compiled period").
    """
    if compiled is None:  # resolved here: workers and cluster nodes run this call's pass
        compiled = threaded.default_compiled()
    elif not isinstance(compiled, (bool, np.bool_)):
        raise UsageError(f"compiled must be True or False, got {compiled!r}")
    if ray is not None or processes is not None:  # lanes elsewhere: bad values are one error
        for name, value in (("threads", threads), ("slots_per_thread", slots_per_thread),
                            ("batch_threads", batch_threads)):  # fmt: skip
            lanes.count(name, value, 1)  # here, before any worker starts
    if ray is not None:
        hooks = observer is not None or profile is not None
        if processes is not None or hooks or threads not in (None, 1):
            raise UsageError("ray runs one lane per cluster CPU: it takes no processes, "
                             "threads, observer or profile")  # fmt: skip
        from mjx_peg.engines import ray_pool

        return ray_pool.run_on_cluster(
            specs, params, config, ray, progress=progress, slots_per_thread=slots_per_thread,
            batch_threads=batch_threads, persistent=persistent, compiled=compiled,
        )  # fmt: skip
    if processes is not None:
        processes = lanes.count("processes", processes, 1)
        if observer is not None or profile is not None:
            raise UsageError("an observer or profile runs in the lane's thread: it needs "
                             "processes=None")  # fmt: skip
        from mjx_peg.engines import processes as worker_processes

        return worker_processes.run_in_processes(
            specs, params, config, processes, threads=threads, progress=progress,
            slots_per_thread=slots_per_thread, batch_threads=batch_threads, persistent=persistent,
            compiled=compiled,
        )  # fmt: skip
    return threaded.run_in_threads(
        specs, params, config, threads=threads, slots_per_thread=slots_per_thread,
        progress=progress, observer=observer, batch_threads=batch_threads, persistent=persistent,
        profile=profile, compiled=compiled,
    )  # fmt: skip
