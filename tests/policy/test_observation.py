"""Observation: both layouts, symmetric yaw encoding, fixed scaling, NumPy = JAX."""

import math

import numpy as np
import pytest

from mjx_peg.policy import observation
from mjx_peg.world import constants
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


def _names_as_written(shape_id, size, pos, yaw):
    """The names layout written out here on purpose (not imported): pose, one-hot, size."""
    order = np.array([0.0, 4.0, 3.0, 6.0, 2.0])[shape_id]
    return np.concatenate(
        [
            (pos - np.array([0.4, 0.0])) / 0.3,
            np.stack([np.cos(order * yaw), np.sin(order * yaw)], axis=-1),
            np.stack([shape_id == i for i in range(3)], axis=-1).astype(np.float64),
            ((size - 0.05) / 0.01)[:, None],
        ],
        axis=-1,
    )


def test_the_names_layout_is_bit_for_bit_the_formula_of_the_shipped_policies():
    specs = sample_trials(TaskConfig(shapes=constants.SHAPES, sizes=(0.025, 0.05, 0.06)), 4, 300)
    expected = _names_as_written(specs.shape_id, specs.size, specs.hole_est_pos, specs.hole_est_yaw)
    for obs in (observation.observe_specs(specs), observation.observe_specs(specs, "names")):
        assert obs.tobytes() == expected.tobytes()
    assert observation.LAYOUTS["names"] == observation.OBS_NAMES
    np.testing.assert_array_equal(expected[specs.shape_id >= 3, 4:7], 0.0)  # no name for them


def _geometry(shape, size, hole_scale, yaw=0.0):
    i = constants.SHAPES.index(shape)
    return observation.observe_geometry(
        np.array([i]), np.array([size]), np.array([hole_scale]), np.array([[0.4, 0.0]]),
        np.array([yaw]),
    )[0]  # fmt: skip


@pytest.mark.parametrize(
    "shape, size, scale, features",
    [  # 1 / n, (r_in - 25 mm) / 10 mm, (r_out - 25 mm) / 10 mm, radial clearance / 1 mm, depth
        ("circle", 0.05, 1.03, (0.0, 0.0, 0.0, 0.75, 1.0)),
        ("square", 0.05, 1.08, (0.25, 0.0, 2.5 * math.sqrt(2) - 2.5, 2.0, 1.0)),
        (
            "triangle",
            0.05,
            1.08,
            (
                1 / 3,
                2.5 / math.sqrt(3) - 2.5,
                5 / math.sqrt(3) - 2.5,
                0.08 * 25 / math.sqrt(3),
                1.0,
            ),
        ),
        ("hexagon", 0.08, 1.02, (1 / 6, 1.5, 8 / math.sqrt(3) - 2.5, 0.8, 1.0)),
        ("rectangle", 0.01, 1.02, (0.5, -2.25, math.sqrt(5) / 4 - 2.5, 0.05, 1.0)),
    ],
)
def test_the_geometry_layout_describes_the_part(shape, size, scale, features):
    obs = _geometry(shape, size, scale)
    assert obs.shape == (len(observation.GEOMETRY_NAMES),) == (9,)
    np.testing.assert_allclose(obs[:4], [0.0, 0.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(obs[4:], features, atol=1e-12)


@pytest.mark.parametrize("shape", constants.SHAPES[1:])
def test_both_layouts_encode_the_yaw_at_the_shape_symmetry(shape):
    n = constants.SYMMETRY[constants.SHAPES.index(shape)]
    for yaw in (0.1, 0.7, -1.3):
        a, b = (
            _geometry(shape, 0.04, 1.05, yaw),
            _geometry(shape, 0.04, 1.05, yaw + 2 * math.pi / n),
        )
        np.testing.assert_allclose(a, b, atol=1e-12)
        half = _geometry(shape, 0.04, 1.05, yaw + math.pi / n)
        np.testing.assert_allclose(half[2:4], -a[2:4], atol=1e-12)
    np.testing.assert_allclose(
        _obs(constants.SHAPES.index(shape), [0.3])[:, 2:4],
        _geometry(shape, 0.05, 1.08, 0.3)[None, 2:4],
        atol=1e-12,
    )


def test_the_geometry_layout_tells_every_part_apart_and_stays_order_one():
    specs = sample_trials(
        TaskConfig(shapes=constants.SHAPES, sizes=(0.01, 0.03, 0.05, 0.08), hole_scale="tight"),
        5, 400,
    )  # fmt: skip
    obs = observation.observe_specs(specs, "geometry")
    assert obs.shape == (400, 9) and np.all(np.abs(obs) <= 3.5)
    parts = {(int(i), round(float(z), 9)) for i, z in zip(specs.shape_id, specs.size, strict=True)}
    described = {tuple(np.round(o[4:], 9)) for o in obs}
    assert len(parts) == len(described) == 20
    with pytest.raises(ValueError, match="unknown observation layout 'pixels'"):
        observation.observe_specs(specs, "pixels")


def test_geometry_numpy_and_jax_agree():
    jnp = pytest.importorskip("jax.numpy")
    specs = sample_trials(TaskConfig(shapes=constants.SHAPES, hole_scale=(1.02, 1.08)), 1, 64)
    a = observation.observe_specs(specs, "geometry")
    b = observation.observe_geometry(
        jnp.asarray(specs.shape_id),
        jnp.asarray(specs.size, jnp.float32),
        jnp.asarray(specs.hole_scale, jnp.float32),
        jnp.asarray(specs.hole_est_pos, jnp.float32),
        jnp.asarray(specs.hole_est_yaw, jnp.float32),
    )
    np.testing.assert_allclose(a, np.asarray(b), atol=2e-6)
