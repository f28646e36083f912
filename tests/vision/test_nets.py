"""vision/nets.py: the Flax networks' output shapes on the real views, their parameter names as
forward.py reads them, and the explicit 1 px zero padding of a 3x3 convolution."""

from __future__ import annotations

import jax
import numpy as np

from mjx_peg.vision.forward import DEFAULT_ARCH, DETECTOR_HEAD, FINE_OUTPUTS
from mjx_peg.vision.nets import Detector, build, flat_params
from mjx_peg.vision.views import ViewConfig


def test_the_default_networks_map_the_views_to_their_outputs():
    """The detector gives one cell per 8 x 8 coarse pixels (the view's coarse_cells), three
    numbers each; the regressor 12 numbers per fine view; flat names layer by layer."""
    det, reg = build(DEFAULT_ARCH)
    views = ViewConfig()
    coarse = jax.ShapeDtypeStruct((2, views.coarse_rows, views.coarse_cols, 3), np.float32)
    fine = jax.ShapeDtypeStruct((2, views.fine_size, views.fine_size, 3), np.float32)
    key = jax.random.key(0)
    det_params = jax.eval_shape(det.init, key, coarse)
    reg_params = jax.eval_shape(reg.init, key, fine)
    det_zeros, reg_zeros = (jax.tree.map(lambda s: np.zeros(s.shape, s.dtype), p)
                            for p in (det_params, reg_params))  # fmt: skip
    assert jax.eval_shape(det.apply, det_params, coarse).shape == (2, 16, 27, DETECTOR_HEAD)
    assert (16, 27) == views.coarse_cells
    assert jax.eval_shape(reg.apply, reg_params, fine).shape == (2, FINE_OUTPUTS)
    convs = len(DEFAULT_ARCH["detector"]["convs"])
    names = sorted(flat_params("detector", det_zeros))
    assert names == sorted(
        [f"detector/conv{i}/{leaf}" for i in range(convs) for leaf in ("bias", "kernel")]
        + ["detector/head/bias", "detector/head/kernel"]
    )
    dense = len(DEFAULT_ARCH["regressor"]["dense"])
    assert {n.split("/")[1] for n in flat_params("regressor", reg_zeros)} == {
        *(f"conv{i}" for i in range(len(DEFAULT_ARCH["regressor"]["convs"]))),
        *(f"dense{i}" for i in range(dense)),
        "out",
    }


def test_a_3x3_convolution_pads_one_zero_pixel():
    """A 3x3 box of ones over an image of ones counts the pixels inside: 4 at a corner, 6 on an
    edge, 9 within; the 1x1 head passes it on; a stride of 2 keeps rows 0, 2 and columns 0, 2, 4."""
    for stride, expected in ((1, [[4, 6, 6, 6, 4], [6, 9, 9, 9, 6], [6, 9, 9, 9, 6],
                                  [4, 6, 6, 6, 4]]),
                             (2, [[4, 6, 4], [6, 9, 6]])):  # fmt: skip
        det = Detector(((1, stride),))
        x = np.ones((1, 4, 5, 1), np.float32)
        head = np.zeros((1, 1, 1, DETECTOR_HEAD), np.float32)
        head[..., 0] = 1.0
        params = {"params": {
            "conv0": {"kernel": np.ones((3, 3, 1, 1), np.float32), "bias": np.zeros(1, np.float32)},
            "head": {"kernel": head, "bias": np.zeros(DETECTOR_HEAD, np.float32)},
        }}  # fmt: skip
        out = np.asarray(det.apply(params, x))
        np.testing.assert_array_equal(out[0, :, :, 0], expected)
        np.testing.assert_array_equal(out[0, :, :, 1:], 0.0)
        assert flat_params("detector", params)["detector/conv0/kernel"].shape == (3, 3, 1, 1)
