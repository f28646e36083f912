"""Shared test set-up: headless rendering, a persistent JAX compilation cache, Python's bytecode
written, the NumPy pass."""

import os
import pathlib

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("JAX_PLATFORMS", "cpu")
_ROOT = pathlib.Path(__file__).resolve().parent.parent
_CACHE = _ROOT / ".jax_cache"
os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(_CACHE))
# Every program, the small ones too: each subprocess that trains (or runs the compiled pass)
# would compile ~50 programs of ~0.1 s afresh (a warm `train.py` of the tiny run: 20 -> 14 s).
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
# Python's bytecode written for the package, also where the environment turns it off: each of the
# suite's Python processes would compile its ~20,000 lines again (~0.5 s each).
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
# The CPU engine's NumPy pass, the reference, unless a test names the compiled one: a compile per
# trial config would cost the suite minutes (tests/engines/test_compiled.py checks the other).
os.environ.setdefault("MJX_PEG_CONTROL_PASS", "numpy")


import pytest  # noqa: E402


@pytest.fixture
def paper_38() -> pathlib.Path:
    """The `paper` policy shipped until 2026-12 (the 38 alone, the names layout, trained with the
    `search` skill), kept for the tests of what only it has and of what was measured with it."""
    return _ROOT / "docs/design/data/learning/paper_search_38"


@pytest.fixture
def x64():
    """Enable float64 in JAX for one test and restore the previous setting (it is global)."""
    import jax

    previous = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", True)
    yield
    jax.config.update("jax_enable_x64", previous)


@pytest.fixture
def hold_out():
    """hold_out(out): a process that holds output directory `out` (`outdir.exclusive`) until it
    is killed (by the test, or when the test ends); returns the process once it holds it."""
    import subprocess
    import sys

    holders = []

    def start(out):
        holder = subprocess.Popen(
            [sys.executable, "-c", "import sys, time; from mjx_peg import outdir\n"
             "with outdir.exclusive(sys.argv[1]):\n    print('held', flush=True); time.sleep(600)",
             str(out)],
            stdout=subprocess.PIPE, text=True,
        )  # fmt: skip
        holders.append(holder)
        assert holder.stdout.readline().strip() == "held"
        return holder

    yield start
    for holder in holders:
        holder.kill()
        holder.wait()
