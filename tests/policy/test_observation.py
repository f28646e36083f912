"""Observation: symmetric yaw encoding, fixed scaling, NumPy = JAX."""

import math

import numpy as np
import pytest

from mjx_peg.policy import observation
from mjx_peg.world.task import TaskConfig, sample_trials


def _obs(shape_id, yaw, size=0.05, pos=(0.45, 0.1)):
    n = len(yaw)
    return observation.observe(
        np.full(n, shape_id), np.full(n, size), np.tile(np.asarray(pos), (n, 1)), np.asarray(yaw)
    )


@pytest.mark.parametrize("shape_id, period", [(1, math.pi / 2), (2, 2 * math.pi / 3)])
def test_yaw_encoding_respects_the_shape_symmetry(shape_id, period):
    yaw = np.linspace(-1.0, 1.0, 7)
    a, b = _obs(shape_id, yaw), _obs(shape_id, yaw + period)
    np.testing.assert_allclose(a, b, atol=1e-12)
    # and distinguishes yaws within one period
    half = _obs(shape_id, yaw + period / 2)
    assert np.all(np.abs(a[:, 2:4] - half[:, 2:4]).max(axis=1) > 1.0)


def test_circle_yaw_is_ignored_and_features_are_scaled():
    a = _obs(0, np.linspace(0, 3, 5))
    assert np.all(a[:, 2] == 1.0) and np.all(a[:, 3] == 0.0)
    np.testing.assert_allclose(a[0, :2], [(0.45 - 0.4) / 0.3, 0.1 / 0.3])
    np.testing.assert_array_equal(a[0, 4:7], [1, 0, 0])
    assert a[0, 7] == 0.0
    sizes = observation.observe(
        np.array([0, 1, 2]), np.array([0.025, 0.05, 0.06]), np.zeros((3, 2)), np.zeros(3)
    )
    np.testing.assert_allclose(sizes[:, 7], [-2.5, 0.0, 1.0], atol=1e-12)
    np.testing.assert_array_equal(sizes[:, 4:7], np.eye(3))


def test_default_workspace_maps_to_order_one_inputs():
    specs = sample_trials(TaskConfig(shapes=("circle", "square", "triangle")), 0, 2000)
    obs = observation.observe_specs(specs)
    assert obs.shape == (2000, observation.OBS_SIZE)
    assert np.all(np.abs(obs) <= 2.5)


def test_numpy_and_jax_agree():
    jnp = pytest.importorskip("jax.numpy")
    specs = sample_trials(TaskConfig(shapes=("circle", "square", "triangle")), 1, 64)
    a = observation.observe_specs(specs)
    b = observation.observe(
        jnp.asarray(specs.shape_id),
        jnp.asarray(specs.size, jnp.float32),
        jnp.asarray(specs.hole_est_pos, jnp.float32),
        jnp.asarray(specs.hole_est_yaw, jnp.float32),
    )
    np.testing.assert_allclose(a, np.asarray(b), atol=2e-6)
