"""The localizer's networks as plain NumPy (the portable export's forward pass; no JAX).

Two small CNNs, described by a JSON-able architecture and run here from a flat dict of arrays
(`model.npz`); `nets.py` builds the same networks in Flax for training, with the same parameter
names, and tests/vision/test_vision.py checks that both agree.

- detector (coarse view, (B, 128, 216, 3) -> (B, 16, 27, 3)): six 3x3 convolutions (ReLU; stride
  2 three times; receptive field 55 px = 330 mm, a whole board), then a 1x1 head per 48 mm
  cell: [board-centre logit, row offset, column offset] (offsets through a sigmoid, in cells).
  A keypoint heatmap (softmax over the cells, as YOLO/CenterNet detect): translation-equivariant,
  so it finds the board anywhere in the workspace and learns "board with a hole", not "bright
  blob"; direct regression of x, y from the whole workspace would have to learn each position.
- regressor (fine view, (B, 112, 112, 3) -> (B, 12)): 3x3 convolutions down to 7 x 7, a dense
  layer, and direct regression: [dx, dy] (the hole centre from the view's centre, world axes,
  in units of OFFSET_SCALE), [cos 4 yaw, sin 4 yaw, cos 3 yaw, sin 3 yaw] (the yaw encoded at the
  square's and the triangle's symmetry, as observation.py encodes it), 3 shape logits, 3 size
  logits. Direct regression here because the view is already centred within ~1.5 cm: one pass
  reads sub-pixel position, yaw and class together from the whole rim.
"""

from __future__ import annotations

import numpy as np

from mjx_peg.world import constants

OFFSET_SCALE = 0.01  # m: the regressor's dx, dy unit
# The size head's classes are world.constants.SIZES_MM, the shape head's the paper's three
# shapes (PAPER_SHAPES), in order.
SIZES_MM = constants.SIZES_MM
SHAPE_CLASSES = constants.PAPER_SHAPES
FINE_OUTPUTS = 12
DETECTOR_HEAD = 3

DEFAULT_ARCH = {
    "detector": {"convs": [[12, 2], [24, 2], [24, 1], [32, 2], [32, 1], [32, 1]]},
    "regressor": {
        "convs": [[16, 2], [24, 1], [32, 2], [32, 1], [48, 2], [48, 1], [64, 2]],
        "dense": [128],
    },
}


MAX_FEATURES, MAX_STRIDE, MAX_LAYERS = 1024, 4, 16  # an architecture larger than this is refused


def _layers(value, what: str, pairs: bool) -> list:
    ok = isinstance(value, list) and len(value) <= MAX_LAYERS
    for item in value if ok else ():
        if pairs:
            ok = ok and isinstance(item, list) and len(item) == 2
            ok = ok and all(type(v) is int for v in item)
            ok = ok and 1 <= item[0] <= MAX_FEATURES and 1 <= item[1] <= MAX_STRIDE
        else:
            ok = ok and type(item) is int and 1 <= item <= MAX_FEATURES
    if not ok:
        form = "[features, stride] pairs" if pairs else "widths"
        raise ValueError(f"{what} is not a list of at most {MAX_LAYERS} {form}")
    return value


def param_shapes(arch, fine_size: int) -> dict[str, tuple[int, ...]]:
    """{name: shape} of every array the forward passes read for the architecture `arch` (the
    JSON form of DEFAULT_ARCH) and fine views of fine_size px; ValueError if `arch` is not
    one."""
    if not isinstance(arch, dict) or not all(
        isinstance(arch.get(k), dict) for k in ("detector", "regressor")
    ):
        raise ValueError("arch is not {detector: {...}, regressor: {...}}")
    shapes, channels = {}, 3
    for i, (features, _) in enumerate(
        _layers(arch["detector"].get("convs"), "detector.convs", True)
    ):
        shapes[f"detector/conv{i}/kernel"] = (3, 3, channels, features)
        shapes[f"detector/conv{i}/bias"] = (features,)
        channels = features
    shapes["detector/head/kernel"] = (1, 1, channels, DETECTOR_HEAD)
    shapes["detector/head/bias"] = (DETECTOR_HEAD,)
    channels, side = 3, fine_size
    for i, (features, stride) in enumerate(
        _layers(arch["regressor"].get("convs"), "regressor.convs", True)
    ):
        shapes[f"regressor/conv{i}/kernel"] = (3, 3, channels, features)
        shapes[f"regressor/conv{i}/bias"] = (features,)
        channels, side = features, -(-side // stride)
    width = side * side * channels
    for i, units in enumerate(_layers(arch["regressor"].get("dense"), "regressor.dense", False)):
        shapes[f"regressor/dense{i}/kernel"] = (width, units)
        shapes[f"regressor/dense{i}/bias"] = (units,)
        width = units
    shapes["regressor/out/kernel"] = (width, FINE_OUTPUTS)
    shapes["regressor/out/bias"] = (FINE_OUTPUTS,)
    return shapes


def conv2d(x: np.ndarray, kernel: np.ndarray, bias: np.ndarray, stride: int) -> np.ndarray:
    """(B, H', W', F) 'same'-padded (1 px) 3x3 or unpadded 1x1 convolution of (B, H, W, C)
    with kernel (k, k, C, F) (Flax's layout), stride `stride`."""
    k = kernel.shape[0]
    if k == 1:
        return x[:, ::stride, ::stride] @ kernel[0, 0] + bias
    pad = (k - 1) // 2
    xp = np.pad(x, ((0, 0), (pad, pad), (pad, pad), (0, 0)))
    win = np.lib.stride_tricks.sliding_window_view(xp, (k, k), axis=(1, 2))[:, ::stride, ::stride]
    # win: (B, H', W', C, k, k)
    return np.tensordot(win, kernel.transpose(2, 0, 1, 3), axes=([3, 4, 5], [0, 1, 2])) + bias


def _relu(x):
    return np.maximum(x, 0.0)


def detector_forward(arch: dict, params: dict, x: np.ndarray) -> np.ndarray:
    """(B, h, w, 3) raw head outputs of the detector for standardized views x (B, H, W, 3)."""
    x = np.asarray(x, dtype=np.float32)
    for i, (_, stride) in enumerate(arch["convs"]):
        x = _relu(
            conv2d(x, params[f"detector/conv{i}/kernel"], params[f"detector/conv{i}/bias"], stride)
        )
    return conv2d(x, params["detector/head/kernel"], params["detector/head/bias"], 1)


def regressor_forward(arch: dict, params: dict, x: np.ndarray) -> np.ndarray:
    """(B, 12) raw outputs of the regressor for standardized views x (B, S, S, 3)."""
    x = np.asarray(x, dtype=np.float32)
    for i, (_, stride) in enumerate(arch["convs"]):
        x = _relu(
            conv2d(
                x, params[f"regressor/conv{i}/kernel"], params[f"regressor/conv{i}/bias"], stride
            )
        )
    x = x.reshape(x.shape[0], -1)
    for i in range(len(arch["dense"])):
        x = _relu(x @ params[f"regressor/dense{i}/kernel"] + params[f"regressor/dense{i}/bias"])
    return x @ params["regressor/out/kernel"] + params["regressor/out/bias"]


def sigmoid(x):
    return 1.0 / (1.0 + np.exp(-x))


def softmax(x, axis=-1):
    e = np.exp(x - x.max(axis=axis, keepdims=True))
    return e / e.sum(axis=axis, keepdims=True)
