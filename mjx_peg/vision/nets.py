"""The localizer's networks in Flax (training); `forward.py` runs the same ones in NumPy.

Parameter names match forward.py's: `conv{i}`, `head`, `dense{i}`, `out`; padding is explicit
(1 px for 3x3) so both agree exactly.
"""

from __future__ import annotations

import flax.linen as nn
import jax.numpy as jnp

from mjx_peg.vision.forward import DETECTOR_HEAD, FINE_OUTPUTS


class Detector(nn.Module):
    """Coarse view (B, H, W, 3) -> (B, H/8, W/8, 3): [centre logit, row, col offset logits]."""

    convs: tuple[tuple[int, int], ...]

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        for i, (features, stride) in enumerate(self.convs):
            conv = nn.Conv(
                features, (3, 3), strides=stride, padding=((1, 1), (1, 1)), name=f"conv{i}"
            )
            x = nn.relu(conv(x))
        return nn.Conv(DETECTOR_HEAD, (1, 1), padding="VALID", name="head")(x)


class Regressor(nn.Module):
    """Fine view (B, S, S, 3) -> (B, 12): offset, yaw encodings, shape and size logits."""

    convs: tuple[tuple[int, int], ...]
    dense: tuple[int, ...]

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        for i, (features, stride) in enumerate(self.convs):
            conv = nn.Conv(
                features, (3, 3), strides=stride, padding=((1, 1), (1, 1)), name=f"conv{i}"
            )
            x = nn.relu(conv(x))
        x = x.reshape(x.shape[0], -1)
        for i, width in enumerate(self.dense):
            x = nn.relu(nn.Dense(width, name=f"dense{i}")(x))
        return nn.Dense(FINE_OUTPUTS, name="out")(x)


def build(arch: dict) -> tuple[Detector, Regressor]:
    """The two Flax modules of an architecture dict (forward.DEFAULT_ARCH's layout)."""
    det = Detector(tuple(tuple(c) for c in arch["detector"]["convs"]))
    reg = Regressor(
        tuple(tuple(c) for c in arch["regressor"]["convs"]), tuple(arch["regressor"]["dense"])
    )
    return det, reg


def flat_params(name: str, params) -> dict:
    """{'name/layer/kernel': array} of a Flax params tree ({'params': {layer: {...}}} or bare)."""
    import numpy as np

    tree = params.get("params", params)
    return {
        f"{name}/{layer}/{leaf}": np.asarray(value, dtype=np.float32)
        for layer, leaves in tree.items()
        for leaf, value in leaves.items()
    }
