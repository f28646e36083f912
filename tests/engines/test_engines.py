"""engines/__init__.py: `run_trials` checks its input and runs the engine `resolve_engine` picks
(C MuJoCo and MJX agree: tests/engines/test_mjx.py)."""

import numpy as np
import pytest

from mjx_peg.engines import engine_runner, mujoco, resolve_engine, run_trials
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials


def _specs(shape, n, seed, **errors):
    config = TaskConfig(shapes=(shape,), sizes=(0.05,), **errors)
    return sample_trials(config, seed, n)


def test_bad_input_is_one_clear_error():
    specs = _specs("square", 2, seed=4)
    with pytest.raises(ValueError, match="unknown engine"):
        run_trials(specs, baseline_params(), engine="bullet")
    bad = baseline_params().copy()
    bad[5] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        run_trials(specs, bad, engine="mujoco")
    with pytest.raises(ValueError, match="shape"):
        run_trials(specs, np.zeros(37), engine="mujoco")
    with pytest.raises(ValueError, match="specs must be a TrialSpec, got str"):
        run_trials("not specs", baseline_params(), engine="mujoco")
    with pytest.raises(ValueError, match="specs holds no trials"):
        run_trials(specs.take([]), baseline_params(), engine="mujoco")


def test_auto_is_the_cpu_engine_where_jax_sees_no_accelerator():
    """The tests run JAX on its CPU back-end (tests/conftest.py): auto resolves to mujoco."""
    import jax

    assert {d.platform for d in jax.devices()} == {"cpu"}
    assert resolve_engine("auto") == "mujoco"
    assert resolve_engine("mujoco") == "mujoco" and resolve_engine("mjx") == "mjx"
    with pytest.raises(ValueError, match="unknown engine 'MJX': choose from auto, mujoco, mjx"):
        resolve_engine("MJX")


def test_each_engine_has_its_runner():
    assert engine_runner("mujoco") is mujoco.run_on_cpu
    with pytest.raises(ValueError, match="unknown engine 'auto': choose mujoco or mjx"):
        engine_runner("auto")  # resolved first (resolve_engine)
