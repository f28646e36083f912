"""engines/interrupt.py: a stop request reaches engine calls wherever they run."""

import os
import signal
import time

import pytest

from mjx_peg.engines import interrupt


def test_a_request_stands_until_cleared():
    interrupt.clear()
    assert not interrupt.requested()
    interrupt.check()  # nothing requested: returns
    interrupt.request()
    try:
        assert interrupt.requested()
        with pytest.raises(KeyboardInterrupt):
            interrupt.check()
        with pytest.raises(KeyboardInterrupt):
            interrupt.check()  # still standing: every running call stops
    finally:
        interrupt.clear()
    assert not interrupt.requested()


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_and_sigterm_request_the_stop_while_the_main_thread_waits(signum):
    """Inside `on_stop_signals` either signal reaches the engines through the wakeup fd, without
    the main thread running Python (training waits in a jitted iteration; a SIGTERM waited for
    the iteration's end, a minute and more)."""
    previous = signal.signal(signum, lambda *_: None)  # a Python handler, as a command has
    interrupt.clear()
    try:
        with interrupt.on_stop_signals():
            os.kill(os.getpid(), signum)
            deadline = time.monotonic() + 5.0
            while not interrupt.requested() and time.monotonic() < deadline:
                time.sleep(0.01)
            assert interrupt.requested()
        assert not interrupt.requested()  # cleared as the block ends
    finally:
        signal.signal(signum, previous)
        interrupt.clear()
