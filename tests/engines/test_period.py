"""The trial's period, written once: the same numbers on NumPy and on JAX, and each rule once."""

import pathlib
import re

import numpy as np
import pytest

from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines import period
from mjx_peg.engines.trial import TrialConfig, as_controller_params, control_config, fitted_basis
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials

ENGINES = pathlib.Path(period.__file__).parent


class _Captured(Exception):
    pass


def _capture(steps: set[int], config: TrialConfig):
    """(consts, state, measurement) of a C-engine lane at the first period of each of `steps`."""
    task = TaskConfig(shapes=("circle", "square", "triangle"), linear_error=0.004,
                      angular_error=np.deg2rad(6.0), sensor_noise_scale=(0.5, 2.0))  # fmt: skip
    specs = sample_trials(task, 4, 6)
    params = as_controller_params(baseline_params(), len(specs))
    got = {}

    def observe(lane, rows, wrench):
        step = int(lane.step[0])
        if step in steps and step not in got:
            copy = lambda a: np.array(a, copy=True)  # noqa: E731
            got[step] = tuple(
                period.tree_map(copy, tree)
                for tree in (lane.consts, lane.state, lane.measurement(lane.measured))
            )
            if len(got) == len(steps):
                raise _Captured

    with pytest.raises(_Captured):
        cpu_engine.run_on_cpu(specs, params, config, threads=1, observer=observe)
    return got


def _leaves(trees) -> list:
    out: list = []
    for tree in trees:
        period.tree_map(out.append, tree)
    return out


@pytest.mark.parametrize("deadband", [(0.0, 0.0), (2.0, 0.4)])
def test_period_is_the_same_on_numpy_and_jax(deadband):
    """`period.period` and `period.result` on a lane's real rows (at the start, in contact, at a
    settle window's close), with and without the wrench's dead band: NumPy and JAX (float64,
    jitted) agree within 1e-6 (relative)."""
    import jax
    import jax.numpy as jnp

    config = TrialConfig(time_limit_s=6.0, force_deadband=deadband[0], moment_deadband=deadband[1])
    w = config.settle_steps
    captured = _capture({0, 700, 5 * w - 1}, config)
    control, basis = control_config(config), fitted_basis(config.dmp)

    def run(xp, consts, state, meas):
        end, new, torques, wrench = period.period(
            config, control_config(config, xp), basis, consts, state, meas
        )
        return end, new, torques, wrench, period.result(config, consts, state, meas.tip_pos, end)

    with jax.enable_x64(True):
        jitted = jax.jit(lambda c, s, m: run(jnp, c, s, m))
        for step, (consts, state, meas) in captured.items():
            to_jax = lambda a: jnp.asarray(a)  # noqa: E731
            on_jax = jitted(*(period.tree_map(to_jax, t) for t in (consts, state, meas)))
            copies = [period.tree_map(lambda a: np.array(a, copy=True), t)
                      for t in (consts, state, meas)]  # fmt: skip
            on_numpy = run(np, *copies)
            flat_np, flat_jax = _leaves(on_numpy), _leaves(on_jax)
            assert len(flat_np) > 20
            for a, b in zip(flat_np, flat_jax, strict=True):
                b = np.asarray(b)
                assert a.shape == b.shape, step
                if a.dtype == bool or np.issubdtype(a.dtype, np.integer):
                    np.testing.assert_array_equal(a, b, err_msg=f"step {step}")
                else:
                    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-9, err_msg=f"step {step}")
    assert control.torque_limits.shape == (6,)


def test_each_rule_of_the_trial_is_written_once():
    """The protective stop, the chatter metric, the damping and the end tests appear in
    engines/period.py only, not in either engine."""
    rules = {
        "protective stop": r"\.max_tool_force\b",
        "chatter ring": r"ring_write\(|chatter_ring\[",
        "compliance damping": r"\.coupling_pole\b",
        "success test": r"is_success\(",
        "speed test": r"\.max_joint_speed\b",
        "settle test": r"settle_update\(",
        "settled ending": r"is_settled\(",
        "time limit": r"\.max_steps\b",
    }
    for name, pattern in rules.items():
        where = {
            path.name: len(re.findall(pattern, path.read_text()))
            for path in ENGINES.glob("*.py")
            if path.name != "trial.py"  # the definitions
        }
        where = {k: v for k, v in where.items() if v}
        assert list(where) == ["period.py"] and where["period.py"] == 1, (name, where)
