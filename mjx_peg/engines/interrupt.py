"""A Ctrl-C or SIGTERM for engine calls that run where the signal cannot reach: JAX host callbacks.

Python delivers a signal to the main thread between bytecodes; while that thread waits in a
jitted computation (the trainer's PPO iteration, whose environment runs the CPU engine in a
`jax.pure_callback` on another thread), it would act only when the iteration ends
(`on_stop_signals` acts at once). A caller that installs its own handler calls `request()`
there: every running CPU-engine call stops at its lanes' next control period (or the process
pool's next poll, 50 ms) and raises KeyboardInterrupt, which ends the computation with an error
at once.
"""

from __future__ import annotations

import contextlib
import logging
import os
import select
import signal
import threading
from typing import NoReturn

from mjx_peg import signals

_REQUESTED = threading.Event()


def request() -> None:
    """Stop the engine calls running now, and any started before `clear()`."""
    _REQUESTED.set()


def requested() -> bool:
    return _REQUESTED.is_set()


def clear() -> None:
    _REQUESTED.clear()


def check() -> None:
    """KeyboardInterrupt if a stop was requested (`stop`)."""
    if _REQUESTED.is_set():
        stop()


def stop() -> NoReturn:
    """Raise the requested stop as KeyboardInterrupt, the command's signal handling told first
    (`signals.unwinding`): the signal's own handler, retrying after an unsafe frame, must not
    raise a second one while the command unwinds."""
    signals.unwinding()
    raise KeyboardInterrupt


class _Quiet(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return not requested()


@contextlib.contextmanager
def on_stop_signals():
    """While the block runs, Ctrl-C (SIGINT) and SIGTERM also call `request()`, even while the
    main thread waits in compiled code: CPython's C-level handler writes the signal to a wakeup
    fd (`signal.set_wakeup_fd`) at once, and a watcher thread reads it. The usual
    KeyboardInterrupt (`signals.Terminated`) still follows in the main thread. Outside the main
    thread, a no-op."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    read, write = os.pipe()
    os.set_blocking(write, False)
    previous = signal.set_wakeup_fd(write)
    done = threading.Event()

    def watch():
        while not done.is_set():
            if select.select([read], [], [], 0.1)[0]:
                received = os.read(read, 64)
                if signal.SIGINT in received or signal.SIGTERM in received:
                    request()

    watcher = threading.Thread(target=watch, name="stop-signal-watcher", daemon=True)
    watcher.start()
    # JAX logs the callback's KeyboardInterrupt with its traceback: not news after a Ctrl-C.
    callbacks = logging.getLogger("jax._src.callback")
    quiet = _Quiet()
    callbacks.addFilter(quiet)
    try:
        yield
    finally:
        callbacks.removeFilter(quiet)
        done.set()
        watcher.join()
        signal.set_wakeup_fd(previous)
        os.close(read)
        os.close(write)
        clear()
