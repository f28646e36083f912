"""The family of parts: each part's cross-section, size and hole clearance.

A part is (shape, size S, hole scale). The shapes are `constants.SHAPES`, each with what its
characteristic size S measures: circle diameter D; square and triangle (equilateral) edge L;
hexagon (regular) width across flats, so its inscribed circle is the circle's of D = S;
rectangle (2:1, a keyed part) long edge S, short edge S/2. Every section then fits an S-by-S
square but the hexagon's corners (1.15 S across), so one S sizes the board, the camera's view and
the arm's reach alike, and the sizes run over `constants.SIZE_RANGE` (10-80 mm).

The hole's clearance is the hole scale, the hole's size over the peg's: the hole is the peg's
section scaled by it about the axis (the round hole is a polygon of boxes whose inscribed
diameter is hole_scale D). The paper's fits are 1.03 D round and 1.08 L for a section with
corners (section 5); the hexagon and the rectangle have corners and take 1.08; tight fits are
1.01 D and 1.02 S (`constants.HOLE_SCALE`, `TIGHT_HOLE_SCALE`). A TaskConfig and the command
lines name clearances by a fit's name, a number, a (low, high) range or a mapping by shape
(`hole_scale_ranges`, `parse_hole_scale`); a range draws from evenly spaced values at most
`constants.HOLE_SCALE_STEP` apart (`hole_scale_values`).

The hole is HOLE_DEPTH (the paper's 80 mm) deep for every part: it is the paper's board, and
the skill measures its depths from the hole's entrance, so a deeper or shallower board would
change the task rather than the part.

The scene builds the hole of boxes, one wall per polygon edge (`hole_walls`: each wall's outward
normal and the distance of its inner face from the axis), and the peg as a box (square,
rectangle) or a convex mesh prism of `peg_section` (MJX has no cylinder collisions); frames
and orientations: `mjcf.py`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from mjx_peg.errors import UsageError
from mjx_peg.world.constants import (
    CIRCLE_SIDES,
    HOLE_FITS,
    HOLE_SCALE,
    HOLE_SCALE_RANGE,
    HOLE_SCALE_STEP,
    HOLE_SIDES,
    SHAPES,
)


def check_part(shape: str, size: float) -> tuple[str, float]:
    """Validated (shape, size in m) or UsageError with one line naming the valid values."""
    if shape not in SHAPES:
        raise UsageError(f"unknown shape {shape!r}: valid shapes are {', '.join(SHAPES)}")
    try:
        size = float(size)
    except (TypeError, ValueError):
        raise UsageError(f"size must be a finite number of metres > 0, got {size!r}") from None
    if not (math.isfinite(size) and size > 0.0):
        raise UsageError(f"size must be a finite number of metres > 0, got {size!r}")
    return shape, size


def check_hole_scale(shape: str, hole_scale: float | None = None) -> float:
    """The hole's clearance (hole size / peg size) of a part: the shape's paper fit for None
    (`constants.HOLE_SCALE`), else a finite number in HOLE_SCALE_RANGE (UsageError otherwise)."""
    if hole_scale is None:
        return HOLE_SCALE[shape]
    lo, hi = HOLE_SCALE_RANGE
    try:
        value = float(hole_scale)
    except (TypeError, ValueError):
        value = math.nan
    if not lo <= value <= hi:
        raise UsageError(
            f"hole scale (hole size / peg size) must be a number in [{lo:g}, {hi:g}], "
            f"got {hole_scale!r}"
        )
    return value


def fit_text(shape: str, hole_scale: float) -> str:
    """What the command lines add to a part's name: " (hole 1.02 S)" for a hole scale other than
    the shape's paper fit, nothing for that fit."""
    return "" if float(hole_scale) == HOLE_SCALE[shape] else f" (hole {float(hole_scale):g} S)"


HoleScaleRanges = tuple[tuple[str, float, float], ...]


def hole_scale_ranges(value) -> HoleScaleRanges:
    """((shape, low, high), ...) in SHAPES order: the hole scales (hole size / peg size) a
    TaskConfig draws for the shapes it names; a shape not named takes its paper fit.

    `value`: None (every shape its paper fit, `constants.HOLE_SCALE`); a fit's name in
    `constants.HOLE_FITS` ("paper", "tight"); a number or a (low, high) range for every shape; a
    mapping shape -> number or range; or this function's own output.
    """
    if value is None or (isinstance(value, Sequence) and not isinstance(value, str) and not value):
        return ()
    if isinstance(value, str):
        if value not in HOLE_FITS:
            raise UsageError(
                f"unknown hole fit {value!r}: choose from {', '.join(HOLE_FITS)}, or give a number"
            )
        value = HOLE_FITS[value]
    if isinstance(value, Mapping):
        items = list(value.items())
    elif (
        isinstance(value, Sequence)
        and value
        and all(isinstance(v, Sequence) and not isinstance(v, str) and len(v) == 3 for v in value)
    ):
        items = [(v[0], v[1:]) for v in value]
    else:
        items = [(shape, value) for shape in SHAPES]
    ranges = {}
    for shape, scale in items:
        if shape not in SHAPES:
            raise UsageError(f"TaskConfig.hole_scale names an unknown shape {shape!r}")
        lo, hi = _scale_pair(scale if isinstance(scale, Sequence) else (scale, scale))
        if lo < HOLE_SCALE_RANGE[0] or hi > HOLE_SCALE_RANGE[1]:
            raise UsageError(
                f"TaskConfig.hole_scale of the {shape} must lie in [{HOLE_SCALE_RANGE[0]:g}, "
                f"{HOLE_SCALE_RANGE[1]:g}] (hole size / peg size), got ({lo:g}, {hi:g})"
            )
        ranges[shape] = (lo, hi)
    return tuple((s, *ranges[s]) for s in SHAPES if s in ranges)


def _scale_pair(value) -> tuple[float, float]:
    """A (low, high) pair of finite hole scales, low <= high (UsageError otherwise)."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise UsageError(
            f"TaskConfig.hole_scale must be a (low, high) pair, got {value!r}"
        ) from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise UsageError(f"TaskConfig.hole_scale must be finite with low <= high, got ({lo}, {hi})")
    return lo, hi


# The command lines' --hole-scale (`parse_hole_scale`).
HOLE_SCALE_HELP = (
    "the hole's clearance, hole size / peg size, of every shape: paper (the paper's fits, 1.03 D "
    "round and 1.08 S with corners; default), tight (1.01 D, 1.02 S) or a number in "
    f"[{HOLE_SCALE_RANGE[0]:g}, {HOLE_SCALE_RANGE[1]:g}]"
)


def parse_hole_scale(text: str) -> str | float:
    """A command line's hole scale: a fit's name (`constants.HOLE_FITS`) or a number in
    HOLE_SCALE_RANGE (UsageError otherwise)."""
    if text in HOLE_FITS:
        return text
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    lo, hi = HOLE_SCALE_RANGE
    if not lo <= value <= hi:
        raise UsageError(
            f"--hole-scale must be {' or '.join(HOLE_FITS)} or a number in [{lo:g}, {hi:g}] "
            f"(hole size / peg size), got {text!r}"
        )
    return value


def hole_scale_of(shape: str, value: str | float | None) -> float:
    """The one hole scale that `value` (None or "paper": the paper's fit; "tight"; a number)
    gives `shape`."""
    value = "paper" if value is None else value
    lo, hi = dict((s, (a, b)) for s, a, b in hole_scale_ranges(value)).get(shape, (None, None))
    if lo is None or lo != hi:
        raise UsageError(f"hole scale {value!r} names no single value for the {shape}")
    return lo


def hole_scale_values(low: float, high: float) -> np.ndarray:
    """The evenly spaced hole scales a (low, high) range draws from: both ends, at most
    HOLE_SCALE_STEP apart (one value if low == high)."""
    return np.linspace(low, high, int(math.ceil((high - low) / HOLE_SCALE_STEP - 1e-9)) + 1)


def hole_walls(
    shape: str, size: float, hole_scale: float | None = None
) -> tuple[tuple[float, float], ...]:
    """((normal angle rad, distance m), ...) of the hole's walls in the board frame: each wall's
    outward normal (HOLE_SIDES[shape] of them, evenly spaced from -90 deg) and the distance of
    its inner face from the hole axis. The hole is the peg's section scaled by hole_scale: circle
    hole_scale D/2, square and hexagon hole_scale S/2, triangle hole_scale L/(2 sqrt 3),
    rectangle hole_scale S/4 (the long edges, normals +-90 deg) and hole_scale S/2."""
    shape, size = check_part(shape, size)
    width = check_hole_scale(shape, hole_scale) * size  # the hole's S
    angles = hole_normal_angles(shape)
    if shape == "triangle":
        distances = [width / (2.0 * math.sqrt(3.0))] * len(angles)
    elif shape == "rectangle":
        distances = [width / 4.0 if k % 2 == 0 else width / 2.0 for k in range(len(angles))]
    else:
        distances = [width / 2.0] * len(angles)
    return tuple((float(a), d) for a, d in zip(angles, distances, strict=True))


def hole_inradius(shape: str, size: float, hole_scale: float | None = None) -> float:
    """The hole's inradius (m), its nearest wall: circle 1.03 D/2, square 1.08 L/2, triangle
    1.08 L/(2 sqrt 3), hexagon 1.08 S/2, rectangle 1.08 S/4 at the paper's fits."""
    return min(d for _, d in hole_walls(shape, size, hole_scale))


def hole_corners(shape: str, size: float, hole_scale: float | None = None) -> np.ndarray:
    """(n, 2) corners of the hole polygon in the board frame (x, y), counter-clockwise: where
    each wall's inner face meets the next one's."""
    walls = np.array(hole_walls(shape, size, hole_scale))
    nxt = np.roll(walls, -1, axis=0)
    normals = np.stack([np.cos(walls[:, 0]), np.sin(walls[:, 0])], axis=-1)
    normals_next = np.stack([np.cos(nxt[:, 0]), np.sin(nxt[:, 0])], axis=-1)
    lines = np.stack([normals, normals_next], axis=1)  # (n, 2, 2): n . p = d for both walls
    return np.linalg.solve(lines, np.stack([walls[:, 1], nxt[:, 1]], axis=-1)[..., None])[..., 0]


def hole_normal_angles(shape: str) -> np.ndarray:
    """Angles (rad, board frame) of the hole edges' outward normals; the first is -90 deg."""
    n = HOLE_SIDES[shape]
    return -0.5 * math.pi + 2.0 * math.pi * np.arange(n) / n


def peg_section(shape: str, size: float) -> np.ndarray:
    """(n, 2) corners of the peg cross-section in the peg frame (x, y), counter-clockwise."""
    shape, size = check_part(shape, size)
    if shape == "rectangle":
        return np.array([[1.0, -0.5], [1.0, 0.5], [-1.0, 0.5], [-1.0, -0.5]]) * (size / 2.0)
    if shape == "circle":
        angles = 2.0 * math.pi * np.arange(CIRCLE_SIDES) / CIRCLE_SIDES
        radius = size / 2.0
    elif shape == "square":
        angles = math.pi / 4 + 0.5 * math.pi * np.arange(4)
        radius = size / math.sqrt(2.0)
    elif shape == "hexagon":
        angles = 2.0 * math.pi * np.arange(6) / 6
        radius = size / math.sqrt(3.0)
    else:
        angles = -0.5 * math.pi + 2.0 * math.pi * np.arange(3) / 3
        radius = size / math.sqrt(3.0)
    return radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)
