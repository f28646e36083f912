"""Shared by the benchmark scripts: the device name, timed calls and BENCHMARKS.md section
updates."""

from __future__ import annotations

import pathlib
import platform
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent


def cpu_name() -> str:
    """The CPU model from /proc/cpuinfo (or what the platform module knows)."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def time_calls(fn, seconds: float) -> float:
    """Median seconds per call over 5 rounds of about `seconds` / 5 each."""
    fn()
    start = time.perf_counter()
    fn()
    once = max(time.perf_counter() - start, 1e-7)
    reps = max(1, int(seconds / 5 / once))
    rounds = []
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(reps):
            fn()
        rounds.append((time.perf_counter() - start) / reps)
    return float(np.median(rounds))


def write_section(path: pathlib.Path, heading: str, section: str) -> None:
    """Replace (or append) the markdown section that starts at `heading`."""
    text = path.read_text() if path.exists() else "# Benchmarks\n"
    start = text.find(heading)
    if start < 0:
        text = text.rstrip() + "\n\n" + section
    else:
        end = text.find("\n## ", start + len(heading))
        text = text[:start] + section + (text[end + 1 :] if end >= 0 else "")
    path.write_text(text)
