"""vision/training.py: the yaw encoding of a mirrored crop is the mirrored hole's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjx_peg.vision.figures import hole_outline
from mjx_peg.vision.training import mirror_encoding


@pytest.mark.parametrize("shape", ["square", "triangle"])
def test_mirrored_yaw_encoding_matches_mirrored_outline(shape):
    n = 4 if shape == "square" else 3
    rng = np.random.default_rng(0)
    for yaw in rng.uniform(0, 2 * math.pi, 5):
        enc = np.array(
            [[math.cos(4 * yaw), math.sin(4 * yaw), math.cos(3 * yaw), math.sin(3 * yaw)]]
        )
        outline = hole_outline(shape, 0.05, 0.0, 0.0, yaw)[:-1, :2]
        for fr, fc in ((True, False), (False, True), (True, True)):
            mirrored = outline * np.array([-1.0 if fr else 1.0, -1.0 if fc else 1.0])
            e = mirror_encoding(enc, np.array([fr]), np.array([fc]))[0]
            c, s = (e[0], e[1]) if n == 4 else (e[2], e[3])
            expected = hole_outline(shape, 0.05, 0.0, 0.0, math.atan2(s, c) / n)[:-1, :2]
            dist = np.linalg.norm(mirrored[:, None] - expected[None], axis=-1).min(axis=1)
            assert dist.max() < 1e-9, (shape, yaw, fr, fc)
