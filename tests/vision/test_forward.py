"""vision/forward.py: the NumPy forward pass of the localizer's networks equals Flax's."""

from __future__ import annotations

import numpy as np

from mjx_peg.vision import forward

FORWARD_TOL = 1e-4  # NumPy export vs Flax, float32


def test_numpy_forward_matches_flax():
    from mjx_peg.vision.nets import build, flat_params
    from mjx_peg.vision.training import init_params

    arch = {
        "detector": {"convs": [[4, 2], [6, 1], [8, 2]]},
        "regressor": {"convs": [[4, 2], [6, 2]], "dense": [8]},
    }
    det, reg = build(arch)
    rng = np.random.default_rng(1)
    xd = rng.normal(size=(2, 32, 24, 3)).astype(np.float32)
    xr = rng.normal(size=(2, 16, 16, 3)).astype(np.float32)
    pd = {"params": init_params(det, xd.shape, rng)}
    pr = {"params": init_params(reg, xr.shape, rng)}
    params = {**flat_params("detector", pd), **flat_params("regressor", pr)}
    np.testing.assert_allclose(
        forward.detector_forward(arch["detector"], params, xd), det.apply(pd, xd), atol=FORWARD_TOL
    )
    np.testing.assert_allclose(
        forward.regressor_forward(arch["regressor"], params, xr),
        reg.apply(pr, xr),
        atol=FORWARD_TOL,
    )
