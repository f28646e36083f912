"""Shared test set-up: headless rendering, a persistent JAX compilation cache, the NumPy pass."""

import os
import pathlib

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("JAX_PLATFORMS", "cpu")
_CACHE = pathlib.Path(__file__).resolve().parent.parent / ".jax_cache"
os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(_CACHE))
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "1")
# The CPU engine's NumPy pass, the reference, unless a test names the compiled one: a compile per
# trial config would cost the suite minutes (tests/engines/test_compiled.py checks the other).
os.environ.setdefault("MJX_PEG_CONTROL_PASS", "numpy")


import pytest  # noqa: E402


@pytest.fixture
def x64():
    """Enable float64 in JAX for one test and restore the previous setting (it is global)."""
    import jax

    previous = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", True)
    yield
    jax.config.update("jax_enable_x64", previous)
