"""The CPU engine's lanes in worker processes: one GIL per process.

`mujoco.run_on_cpu(..., processes=P)` splits the trials into P interleaved shards (trial k goes
to shard k mod P) and runs each in a worker process with `threads` lanes (default 1); results
come back in spec order, bit-identical to running them in this process (a trial's result depends
on its spec and parameters only; under the compiled pass, also on whether it sat in the last
slots of a program: docs/design/compiled_period.md, "A trial's last bits and its slot"). Why: a
lane holds the GIL for its whole NumPy pass, so lanes as threads of one process stop scaling
after a few lanes; processes do not share it (the measurements: docs/design/worker_processes.md).

The workers are spawned on first use and kept for the next call of the same size (a training run
calls the engine once per iteration), each keeping its simulations between calls. A worker dies
with its caller (Linux `PR_SET_PDEATHSIG`), so a SIGKILLed caller leaves nothing running; Ctrl-C
in the caller kills the workers and raises KeyboardInterrupt at once; a worker that dies (a crash
in C) is one clear error, never a hang. Arguments and results travel by `multiprocessing`
between this package's own processes; nothing is read from disk.
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import dataclasses
import multiprocessing
import os
import queue
import signal
import sys
import threading
from collections.abc import Callable
from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import resource_tracker

import numpy as np

from mjx_peg.array_api import tree_map
from mjx_peg.engines import interrupt
from mjx_peg.engines.trial import TrialConfig, TrialResult
from mjx_peg.skill.params import ControllerParams
from mjx_peg.world.task import TrialSpec

_PR_SET_PDEATHSIG = 1
_pool: tuple[int, ProcessPoolExecutor, object] | None = None  # (size, executor, progress queue)
_progress_queue = None  # in a worker: where its finished-trial counts go


def _start_worker(progress_queue, parent: int) -> None:
    """Worker initializer: die with the caller, leave Ctrl-C to it, report progress to it."""
    global _progress_queue
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):  # pragma: no cover - not Linux
        pass
    if os.getppid() != parent:  # the caller died before the line above took effect
        os._exit(0)
    _progress_queue = progress_queue


def _run_shard(specs, params, config, threads, options) -> TrialResult:
    from mjx_peg.engines import threaded

    return threaded.run_in_threads(
        specs, params, config, threads=threads, progress=_progress_queue.put, **options
    )


def _executor(size: int) -> tuple[ProcessPoolExecutor, object]:
    global _pool
    if _pool is not None and _pool[0] == size:
        return _pool[1], _pool[2]
    shutdown()
    ctx = multiprocessing.get_context("spawn")
    progress_queue = ctx.SimpleQueue()
    executor = ProcessPoolExecutor(
        size, mp_context=ctx, initializer=_start_worker, initargs=(progress_queue, os.getpid())
    )
    _pool = (size, executor, progress_queue)
    return executor, progress_queue


def shutdown(kill: bool = False) -> None:
    """Stop the workers (kill: at once, abandoning their calls)."""
    global _pool
    if _pool is None:
        return
    _, executor, _ = _pool
    _pool = None
    if kill:
        for process in list(getattr(executor, "_processes", {}).values()):
            process.kill()
    # Waited for even after a kill (the pool sees its workers gone at once): its queues and
    # their semaphores are then released, not reported as leaked at exit.
    executor.shutdown(wait=True, cancel_futures=True)


atexit.register(shutdown, True)


@contextlib.contextmanager
def _while_workers_start():
    """While workers start: they import this package, never the caller's script (`spawn` would
    run a script again in every worker, and fail on one without a `__main__` guard), and they
    start with SIGINT blocked (a Ctrl-C sent to the whole process group while a worker is still
    importing would print its traceback; the caller stops the workers).

    The queues' semaphores start multiprocessing's resource tracker on first use, and starting
    it unblocks SIGINT in this thread when it is done; it is started here first, before SIGINT is
    blocked, so the block holds while the workers are spawned."""
    resource_tracker.ensure_running()
    main = sys.modules.get("__main__")
    saved = {k: getattr(main, k) for k in ("__file__", "__spec__") if hasattr(main, k)}
    blocked = threading.current_thread() is threading.main_thread()
    if blocked:
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        if "__file__" in saved:
            del main.__file__
        if "__spec__" in saved:
            main.__spec__ = None
        yield
    finally:
        for key, value in saved.items():
            setattr(main, key, value)
        if blocked:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def take_params(params: ControllerParams, rows: np.ndarray) -> ControllerParams:
    """The parameters of the trials at `rows`."""
    return tree_map(lambda a: np.asarray(a)[rows], params)


def interleaved(n: int, shards: int) -> list[np.ndarray]:
    """Row indices of `shards` interleaved shards of n trials (trial k in shard k mod shards)."""
    size = min(shards, n)
    return [np.arange(k, n, size) for k in range(size)]


def merge(n: int, shards: list[np.ndarray], parts: list[TrialResult]) -> TrialResult:
    """The shards' results back in spec order."""
    out = {}
    for field in dataclasses.fields(TrialResult):
        first = getattr(parts[0], field.name)
        merged = np.empty((n, *first.shape[1:]), dtype=first.dtype)
        for rows, part in zip(shards, parts, strict=True):
            merged[rows] = getattr(part, field.name)
        out[field.name] = merged
    return TrialResult(**out)


def run_in_processes(
    specs: TrialSpec,
    params: ControllerParams,
    config: TrialConfig,
    processes: int,
    threads: int | None = None,
    progress: Callable[[int], None] | None = None,
    **options,
) -> TrialResult:
    """Every trial of `specs` on `processes` worker processes of `threads` lanes each (default
    1); `options`: the in-process engine's slots_per_thread, batch_threads, persistent."""
    n = len(specs)
    shards = interleaved(n, processes)
    try:
        with _while_workers_start():  # the executor starts its workers on submit
            executor, progress_queue = _executor(len(shards))
            futures = [
                executor.submit(
                    _run_shard,
                    specs.take(rows),
                    take_params(params, rows),
                    config,
                    threads or 1,
                    options,
                )
                for rows in shards
            ]
        pending = futures
        while pending:
            done, pending = wait(pending, timeout=0.05, return_when=FIRST_EXCEPTION)
            _drain(progress_queue, progress)
            interrupt.check()
            for future in done:
                future.result()  # a worker's error, raised here
        parts = [f.result() for f in futures]
    except BrokenProcessPool:
        shutdown(kill=True)
        raise RuntimeError(
            "a worker process of the CPU engine died (a crash in MuJoCo or out of memory); "
            "rerun with processes=None to see the error in this process"
        ) from None
    except BaseException:  # Ctrl-C or an error in a worker: stop the others at once
        shutdown(kill=True)
        raise
    return merge(n, shards, parts)


def _drain(progress_queue, progress) -> None:
    """Pass the workers' finished-trial counts to `progress` (in the caller's thread)."""
    count = 0
    try:
        while not progress_queue.empty():
            count += progress_queue.get()
    except (OSError, EOFError, queue.Empty):  # pragma: no cover - a worker died mid-message
        pass
    if count and progress is not None:
        progress(count)
