"""Silence the reports that a failed Orbax restore or save leaves behind, and nothing else.

When Orbax cannot read a checkpoint it closes its asyncio loop while TensorStore reads of the
same checkpoint are still in flight. Each of those later ends in one of two reports on stderr:
an unraisable ``RuntimeError('Event loop is closed')`` (TensorStore's callback cannot reach the
closed loop) or an asyncio "Future/Task exception was never retrieved" log record carrying the
read's own error. Whether any is in flight is a race; the caller has already been told, in one
line, that the checkpoint is corrupt. ``expect_failed_reads(directory)`` installs two narrow
filters before the restore starts (the first reports can come before the restore returns): the
unraisable hook drops only that RuntimeError, the log filter drops only records whose exception
names the checkpoint directory. A failed save (a full disk) also logs each failed write with its
traceback through absl from Orbax's threads: ``held_reports()`` holds those records while the
save runs and drops them if it fails (the caller says what failed, in one line).
"""

from __future__ import annotations

import contextlib
import logging
import sys

_directories: set[str] = set()


def _drop_closed_loop(unraisable) -> None:
    exc = unraisable.exc_value
    if isinstance(exc, RuntimeError) and str(exc) == "Event loop is closed":
        return
    _previous_hook(unraisable)


class _DropUnretrievedReads(logging.Filter):
    """Drop asyncio's 'exception was never retrieved' records about reads of a restored run."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        if exc is None or "was never retrieved" not in str(record.msg):
            return True
        return not any(d in str(exc) for d in _directories)


_previous_hook = sys.unraisablehook
_log_filter = _DropUnretrievedReads()


def expect_failed_reads(directory) -> None:
    """Install the filters (once) and let them match reads of ``directory``."""
    global _previous_hook
    _directories.add(str(directory))
    if sys.unraisablehook is not _drop_closed_loop:
        _previous_hook, sys.unraisablehook = sys.unraisablehook, _drop_closed_loop
    logger = logging.getLogger("asyncio")
    if _log_filter not in logger.filters:
        logger.addFilter(_log_filter)


class _Hold(logging.Filter):
    def __init__(self):
        super().__init__()
        self.records: list[logging.LogRecord] = []

    def filter(self, record: logging.LogRecord) -> bool:
        self.records.append(record)
        return False


@contextlib.contextmanager
def held_reports():
    """Hold the records of the "absl" logger (Orbax's) while the block runs; pass them on after
    it, unless it raised."""
    logger = logging.getLogger("absl")
    hold = _Hold()
    logger.addFilter(hold)
    try:
        yield
    finally:
        logger.removeFilter(hold)
    for record in hold.records:
        logger.handle(record)
