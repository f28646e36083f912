"""The cores this process may use: the default of every engine and CLI that runs in parallel."""

from __future__ import annotations

import os


def cores() -> int:
    """Cores this process may use (its CPU affinity, not the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1
