"""vision/figures.py: the hole's outline drawn where the hole is (the paper's clearances), and
the gallery as a 256-colour PNG of its size."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image

from mjx_peg.vision.figures import gallery_png, hole_outline
from mjx_peg.world import constants, parts
from mjx_peg.world.render import save_png


@pytest.mark.parametrize(
    "shape, sides, inradius",
    [
        ("circle", 16, 1.03 * 0.05 / 2),  # the inscribed diameter 1.03 D
        ("square", 4, 1.08 * 0.05 / 2),  # edge 1.08 L
        ("triangle", 3, 1.08 * 0.05 / (2 * math.sqrt(3))),  # equilateral, edge 1.08 L
    ],
)
def test_the_outline_is_the_holes_rim(shape, sides, inradius):
    x, y = 0.42, -0.13
    outline = hole_outline(shape, 0.05, x, y, 0.0)
    assert outline.shape == (sides + 1, 3)
    np.testing.assert_array_equal(outline[0], outline[-1])  # closed
    np.testing.assert_allclose(outline[:, 2], constants.HOLE_DEPTH)  # at the board top
    corners = outline[:-1, :2] - (x, y)
    middles = 0.5 * (corners + np.roll(corners, -1, axis=0))
    np.testing.assert_allclose(np.linalg.norm(middles, axis=1), inradius, rtol=1e-12)
    edges = np.linalg.norm(np.diff(outline[:, :2], axis=0), axis=1)
    np.testing.assert_allclose(edges, 2 * inradius * math.tan(math.pi / sides), rtol=1e-12)
    turned = hole_outline(shape, 0.05, x, y, 0.3)[:-1, :2] - (x, y)
    c, s = math.cos(0.3), math.sin(0.3)
    np.testing.assert_allclose(turned, corners @ np.array([[c, s], [-s, c]]), atol=1e-15)


def test_the_gallery_is_a_paletted_png_of_its_size(tmp_path):
    rng = np.random.default_rng(0)
    items = []
    for k in range(5):
        png = save_png(tmp_path / f"{k}.png", rng.integers(0, 256, (240, 320, 3), np.uint8))
        view = {"distractors": [{}] * k, "table": {"texture": "checker"}}
        items.append((png, {"board": {"shape": "square", "size": 0.05}, "view": view}))
    path = gallery_png(items, tmp_path / "gallery.png", count=5)
    with Image.open(path) as image:
        assert image.mode == "P" and len(image.getpalette()) <= 3 * 256
        assert image.size == (1024, 408)  # 4 columns x 2 rows of 3.2 x 2.55 in at 80 dpi
    names = {p.name for p in tmp_path.iterdir()}
    assert names == {f"{k}.png" for k in range(5)} | {"gallery.png"}  # no partial file left


@pytest.mark.parametrize("shape", constants.SHAPES)
def test_the_drawn_outline_is_the_part_hole(shape):
    corners = parts.hole_corners(shape, 0.04, 1.02)
    outline = hole_outline(shape, 0.04, 0.5, -0.1, 0.0, 1.02)
    np.testing.assert_allclose(outline[:-1, :2], corners + np.array([0.5, -0.1]), atol=1e-15)
    np.testing.assert_allclose(outline[-1], outline[0])
