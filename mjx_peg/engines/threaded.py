"""The CPU engine's lanes in this process, as Python threads, and the control period's pass they
run: `lanes.Lane` (NumPy, the reference) or `compiled.CompiledLane` (XLA).

`run_in_threads` hands the trials out from one `lanes.Queue` to `threads` lanes: while one steps
in C, another runs its pass. Results are bit-identical whatever the threads and slots (tested;
the compiled pass but for a trial's last bits in the last slots of its program:
docs/design/compiled_period.md, "A trial's last bits and its slot").
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable

from mjx_peg.cores import cores
from mjx_peg.engines import interrupt, sims
from mjx_peg.engines.lanes import SLOTS_PER_THREAD, Lane, Queue, count, to_result
from mjx_peg.engines.trial import TrialConfig, TrialResult
from mjx_peg.errors import UsageError
from mjx_peg.skill.params import ControllerParams
from mjx_peg.world.task import TrialSpec

# The environment variable that names the control period's pass of a call that names none:
# "compiled" (XLA, `engines/compiled.py`; the default) or "numpy" (the reference).
PASS_VARIABLE = "MJX_PEG_CONTROL_PASS"
PASSES = ("compiled", "numpy")


LANE_STOP_S = 10.0  # a stopped lane ends within one control period; this is a bound


def run_lanes(specs, params, config, threads: int, slots: int, kind: tuple, source,
              observer=None, profile=None, compiled: bool = False) -> None:  # fmt: skip
    """Run `threads` lanes of `slots` rows on the trials `source` hands out, in this process;
    compiled: their periods compiled (`engines/compiled.py`), else in NumPy.

    The simulations of this call's scenes are kept for the next call, the others dropped.
    """
    count: dict[tuple, int] = {}
    for index in range(len(specs)):
        key = sims.scene_key(specs, index)
        count[key] = count.get(key, 0) + 1
    nsim = {key: min(slots, c) for key, c in count.items()}
    kind_of_lane = Lane
    if compiled:  # imported here: the NumPy pass runs without JAX
        from mjx_peg.engines.compiled import CompiledLane as kind_of_lane
    lanes = [kind_of_lane(specs, params, config, slots, nsim, kind, profile)
             for _ in range(threads)]  # fmt: skip
    errors: list[BaseException] = []

    def work(lane, report=False):
        try:
            lane.run(source, observer, report)
        except BaseException as exc:  # re-raised in the caller's thread
            errors.append(exc)
            source.stop()

    pool: list[threading.Thread] = []
    try:
        if threads == 1:
            work(lanes[0], report=True)
        else:
            pool = [threading.Thread(target=work, args=(lane,), daemon=True) for lane in lanes]
            for t in pool:
                t.start()
            for t in pool:
                while t.is_alive():
                    t.join(timeout=0.05)
                    source.flush()
    except BaseException:  # KeyboardInterrupt: stop the lanes at their next period
        source.stop()
        for t in pool:  # and wait for them: a lane still in MuJoCo at exit would crash it
            if t.is_alive():  # (one whose start was interrupted never ran)
                t.join(timeout=LANE_STOP_S)
        raise
    source.flush()
    sims.keep_sims(set(count))
    if errors:
        raise errors[0]
    interrupt.check()  # the lanes stopped early: their results are incomplete


def default_compiled() -> bool:
    """Whether a call that names no pass runs compiled (PASS_VARIABLE, default compiled)."""
    value = os.environ.get(PASS_VARIABLE, "compiled")
    if value not in PASSES:
        raise UsageError(f"{PASS_VARIABLE} must be one of {', '.join(PASSES)}, got {value!r}")
    return value == "compiled"


def run_in_threads(
    specs: TrialSpec,
    params: ControllerParams,
    config: TrialConfig,
    threads: int | None = None,
    slots_per_thread: int | None = None,
    progress: Callable[[int], None] | None = None,
    observer: Callable | None = None,
    batch_threads: int | None = None,
    persistent: bool | None = None,
    profile: Callable[[str, float], None] | None = None,
    compiled: bool | None = None,
) -> TrialResult:
    """Every trial of `specs` on `threads` lanes in this process (`mujoco.run_on_cpu`' options;
    params batched and validated)."""
    n = len(specs)
    if observer is not None and threads not in (None, 1):
        raise UsageError("an observer runs in the lane's thread: it needs threads=1")
    default = 1 if observer is not None else cores()
    threads = min(count("threads", threads, default), n)
    batch_threads = count("batch_threads", batch_threads, 1)
    slots = count("slots_per_thread", slots_per_thread, 0) or max(
        1, min(SLOTS_PER_THREAD, -(-n // max(threads, 1)))
    )
    queue = Queue(n, progress)
    kind = (batch_threads, None if persistent is None else bool(persistent))
    if n:
        run_lanes(specs, params, config, threads, slots, kind, queue, observer, profile,
                  default_compiled() if compiled is None else bool(compiled))  # fmt: skip
    return to_result(queue.records)
