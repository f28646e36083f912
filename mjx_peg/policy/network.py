"""The policy network's deterministic forward pass: observation -> the skill's numbers.

The network is Brax PPO's policy MLP (`brax.training.agents.ppo.networks`, distribution
"normal" with a state-independent std): hidden Dense layers with swish activations, a linear
mean head. The deterministic action is the mean; `params.controller_from_action` squashes it into
a valid controller, so every output of every network is a usable skill. Observations are
normalized as in training: (obs - mean) / std with Brax's running statistics.

Written over the array-API namespace of the inputs (NumPy on the robot, jax.numpy in tests);
imports neither numpy nor jax at module level. `policy.py` loads the weights from `policy.npz`.
"""

from __future__ import annotations

from collections.abc import Sequence

from mjx_peg.array_api import namespace_of
from mjx_peg.skill.params import (
    controller_from_action,
    controller_from_centred_action,
    vector_from_controller,
)


def swish(x, xp):
    """x * sigmoid(x), written with tanh so that no input overflows (flax's linen.swish)."""
    return x * (0.5 + 0.5 * xp.tanh(0.5 * x))


def mean_action(layers: Sequence[tuple], obs_mean, obs_std, obs):
    """(..., A) deterministic action: the MLP's mean head on the normalized observation.

    layers: [(kernel (in, out), bias (out,)), ...]; every layer but the last is followed by swish.
    """
    xp = namespace_of(obs, obs_mean, obs_std, *[w for layer in layers for w in layer])
    x = (obs - obs_mean) / obs_std
    for i, (kernel, bias) in enumerate(layers):
        x = x @ kernel + bias
        if i < len(layers) - 1:
            x = swish(x, xp)
    return x


def controller_vector(action, centre=None):
    """(..., 38) physical parameter vector [k_t, k_theta, C row-major] of an action: the
    centred map around the physical vector `centre` (38,), or the sigmoid map if None
    (`skill/params.py`)."""
    if centre is None:
        return vector_from_controller(controller_from_action(action))
    return vector_from_controller(controller_from_centred_action(action, centre))
