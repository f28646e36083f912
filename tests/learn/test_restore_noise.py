"""learn/restore_noise.py: after `expect_failed_reads(DIR)` the reports a failed restore of DIR
leaves are dropped, and every other report still reaches stderr's handlers."""

from __future__ import annotations

import logging
import sys
import types

from mjx_peg.learn.restore_noise import expect_failed_reads


def _unraisable(exc):
    return types.SimpleNamespace(exc_value=exc, exc_type=type(exc), exc_traceback=None,
                                 err_msg=None, object=None)  # fmt: skip


def test_only_the_closed_event_loop_is_dropped(tmp_path, monkeypatch):
    seen = []
    monkeypatch.setattr(sys, "unraisablehook", seen.append)
    expect_failed_reads(tmp_path)
    closed = _unraisable(RuntimeError("Event loop is closed"))
    other = _unraisable(RuntimeError("something else"))
    value = _unraisable(ValueError("Event loop is closed"))
    for report in (closed, other, value):
        sys.unraisablehook(report)
    assert seen == [other, value]
    expect_failed_reads(tmp_path)  # twice: still one hook in front of the previous one
    sys.unraisablehook(closed)
    sys.unraisablehook(other)
    assert seen == [other, value, other]


def _never_retrieved(exc, message="Task exception was never retrieved"):
    return logging.LogRecord("asyncio", logging.ERROR, __file__, 1, message, None,
                             (type(exc), exc, None))  # fmt: skip


def test_only_unretrieved_reads_of_the_restored_directory_are_dropped(tmp_path):
    asyncio_log = logging.getLogger("asyncio")
    mine, elsewhere = tmp_path / "checkpoints" / "3", tmp_path / "other"
    expect_failed_reads(mine)
    ours = OSError(f"reading {mine}/array_metadatas/process_0 failed: truncated")
    theirs = OSError(f"reading {elsewhere}/x failed")
    assert not asyncio_log.filter(_never_retrieved(ours))
    assert asyncio_log.filter(_never_retrieved(theirs))
    assert asyncio_log.filter(_never_retrieved(ours, "Future exception in a callback"))
    assert asyncio_log.filter(logging.LogRecord("asyncio", logging.ERROR, __file__, 1,
                                                "Task exception was never retrieved", None,
                                                None))  # fmt: skip
