"""world/constants.py: the parts' radii and symmetry agree with their cross-sections drawn here
from their definitions, every per-shape table covers the family, the clearances lie in their
range, and the module is plain Python."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from mjx_peg.world import constants


def _regular(circumradius: float, n: int, first: float = 0.0) -> list[tuple[float, float]]:
    """The corners of a regular n-gon, the first at angle `first`."""
    angles = first + 2 * math.pi * np.arange(n) / n
    return [(circumradius * math.cos(a), circumradius * math.sin(a)) for a in angles]


# Each cross-section of characteristic size S = 1, its corners counter-clockwise about its axis
# (the circle as a 720-gon), written from the definitions: a square of edge 1, an equilateral
# triangle of edge 1, a regular hexagon 1 across flats, a 1 x 0.5 rectangle.
CORNERS = {
    "circle": _regular(0.5, 720),
    "square": [(0.5, 0.5), (-0.5, 0.5), (-0.5, -0.5), (0.5, -0.5)],
    "triangle": _regular(1.0 / math.sqrt(3.0), 3, math.pi / 2),  # edge 1: circumradius 1 / sqrt 3
    "hexagon": _regular(1.0 / math.sqrt(3.0), 6),  # 1 across flats: circumradius 1 / sqrt 3
    "rectangle": [(0.5, 0.25), (-0.5, 0.25), (-0.5, -0.25), (0.5, -0.25)],
}


def _radii(corners):
    """(inradius, circumradius) of a convex polygon about the origin."""
    p = np.asarray(corners)
    q = np.roll(p, -1, axis=0)
    edge = q - p
    normal = np.stack([edge[:, 1], -edge[:, 0]], axis=1) / np.linalg.norm(edge, axis=1)[:, None]
    return float(np.min(np.abs(np.sum(normal * p, axis=1)))), float(np.max(np.hypot(*p.T)))


def test_every_per_shape_table_covers_the_family():
    assert constants.SHAPES[:3] == constants.PAPER_SHAPES == ("circle", "square", "triangle")
    assert len(constants.SYMMETRY) == len(constants.SHAPES) and constants.SYMMETRY[0] == 0
    for table in (constants.INRADIUS, constants.CIRCUMRADIUS, constants.HOLE_SCALE,
                  constants.TIGHT_HOLE_SCALE, constants.HOLE_SIDES):  # fmt: skip
        assert tuple(table) == constants.SHAPES


@pytest.mark.parametrize("shape", constants.SHAPES)
def test_the_radii_are_the_cross_sections(shape):
    """INRADIUS and CIRCUMRADIUS (over S) of each section drawn from its definition, to 1e-12
    (the circle's 720-gon to 1e-5); every section fits an S-by-S square but the hexagon, whose
    corners span 2 / sqrt(3) = 1.155 S."""
    r_in, r_out = _radii(CORNERS[shape])
    tol = 1e-5 if shape == "circle" else 1e-12
    assert constants.INRADIUS[shape] == pytest.approx(r_in, abs=tol)
    assert constants.CIRCUMRADIUS[shape] == pytest.approx(r_out, abs=tol)
    span = np.ptp(np.asarray(CORNERS[shape]), axis=0).max()
    assert span == pytest.approx(2 / math.sqrt(3) if shape == "hexagon" else 1.0, abs=1e-12)


@pytest.mark.parametrize("shape", constants.SHAPES[1:])
def test_the_symmetry_order_maps_each_section_onto_itself(shape):
    """A turn by 2 pi / n carries the corners onto the corners; no smaller turn (up to 2 pi / 12)
    does."""
    n = constants.SYMMETRY[constants.SHAPES.index(shape)]
    p = np.asarray(CORNERS[shape])

    def turned_onto_itself(angle):
        c, s = math.cos(angle), math.sin(angle)
        q = p @ np.array([[c, s], [-s, c]])
        return all(np.min(np.hypot(*(p - point).T)) < 1e-12 for point in q)

    assert turned_onto_itself(2 * math.pi / n)
    assert not any(turned_onto_itself(2 * math.pi / m) for m in range(n + 1, 13))


def test_the_clearances():
    """The paper's fits (1.03 D round, 1.08 L with corners); tight fits a third of the round
    clearance and a quarter of the polygonal one; both inside the range a scene is built with."""
    low, high = constants.HOLE_SCALE_RANGE
    for shape in constants.SHAPES:
        paper, tight = constants.HOLE_SCALE[shape], constants.TIGHT_HOLE_SCALE[shape]
        assert paper == (1.03 if shape == "circle" else 1.08)
        assert tight - 1 == pytest.approx((paper - 1) / (3 if shape == "circle" else 4))
        assert low <= tight < paper <= high
    assert constants.HOLE_FITS == {"paper": constants.HOLE_SCALE,
                                   "tight": constants.TIGHT_HOLE_SCALE}  # fmt: skip


def test_the_arm_tables_are_six_joints():
    assert constants.JOINT_NAMES == tuple(f"{name}_joint" for name in constants.ACTUATOR_NAMES)
    assert len(constants.ACTUATOR_NAMES) == len(constants.TORQUE_LIMITS) == 6
    assert len(constants.HOME_Q) == 6


def test_the_module_is_plain_python():
    """It imports only the standard library's math: the robot side reads it without NumPy."""
    tree = ast.parse(Path(constants.__file__).read_text())
    imported = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import)
                for alias in node.names}  # fmt: skip
    imported |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert imported == {"math", "__future__"}
