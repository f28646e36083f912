"""policy/network.py: the deterministic forward pass against one written out by hand, in NumPy
and jax.numpy; swish without overflow; an action's 38 numbers by either map."""

from __future__ import annotations

import numpy as np

from mjx_peg.policy import network
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.params import controller_from_action, vector_from_controller


def _by_hand(layers, mean, std, obs):
    """Two swish layers and a linear head, one observation at a time."""
    out = []
    for row in obs:
        x = [(row[i] - mean[i]) / std[i] for i in range(len(row))]
        for depth, (kernel, bias) in enumerate(layers):
            x = [sum(x[i] * kernel[i][j] for i in range(len(x))) + bias[j]
                 for j in range(len(bias))]  # fmt: skip
            if depth < len(layers) - 1:
                x = [v / (1.0 + np.exp(-v)) for v in x]
        out.append(x)
    return np.array(out)


def _network(seed=0):
    rng = np.random.default_rng(seed)
    widths = [(8, 12), (12, 10), (10, 38)]
    layers = [(rng.normal(size=(a, b)), rng.normal(size=b)) for a, b in widths]
    return layers, rng.normal(size=8), rng.uniform(0.5, 2.0, size=8), rng.normal(size=(4, 8))


def test_mean_action_is_the_mlp_written_out():
    layers, mean, std, obs = _network()
    got = network.mean_action(layers, mean, std, obs)
    assert got.shape == (4, 38)
    np.testing.assert_allclose(got, _by_hand(layers, mean, std, obs), rtol=1e-12, atol=1e-12)
    one = network.mean_action(layers, mean, std, obs[1])  # unbatched: (38,)
    np.testing.assert_allclose(one, got[1], rtol=1e-12, atol=1e-12)


def test_mean_action_in_jax_numpy_is_numpys():
    import jax.numpy as jnp

    layers, mean, std, obs = _network(1)
    expected = network.mean_action(layers, mean, std, obs)
    as_jax = [(jnp.asarray(k, jnp.float32), jnp.asarray(b, jnp.float32)) for k, b in layers]
    mean, std, obs = (jnp.asarray(a, jnp.float32) for a in (mean, std, obs))
    got = network.mean_action(as_jax, mean, std, obs)
    assert isinstance(got, jnp.ndarray)
    np.testing.assert_allclose(np.asarray(got), expected, rtol=1e-4, atol=1e-4)


def test_swish_is_x_sigmoid_x_and_never_overflows():
    x = np.array([-3.0, -0.5, 0.0, 0.5, 3.0])
    np.testing.assert_allclose(network.swish(x, np), x / (1 + np.exp(-x)), rtol=1e-15, atol=1e-16)
    with np.errstate(over="raise"):
        big = network.swish(np.array([-1000.0, 1000.0]), np)
    np.testing.assert_array_equal(big, [-0.0, 1000.0])


def test_an_action_becomes_38_numbers_by_either_map():
    action = np.random.default_rng(2).normal(size=(3, 38))
    np.testing.assert_array_equal(
        network.controller_vector(action), vector_from_controller(controller_from_action(action))
    )
    centre = baseline_params()
    np.testing.assert_allclose(network.controller_vector(np.zeros(38), centre), centre,
                               rtol=1e-12)  # fmt: skip
    moved = network.controller_vector(action, centre)
    assert moved.shape == (3, 38) and not np.allclose(moved, centre)
