"""What the policy sees of a trial: the estimated hole pose and the part, in one of two layouts.

The paper's network maps the hole's estimated pose, shape and size to the 38 controller numbers
(section 4.3); ours also to the contact search's constants. Everything here is what the robot
knows before it moves: the vision estimate of the hole (never the true pose) and the part it
holds. Features are scaled to O(1) by fixed,
documented constants, so a value never seen in training (a 60 mm peg, a triangle) is a bounded
input rather than a division by a near-zero running std. Two layouts (`LAYOUTS`); a policy's
manifest records the one it was trained with:

`names` (the shipped `paper`'s and `transfer`'s), 8 numbers:

    0-1   (hole_est_x - 0.4 m) / 0.3 m, hole_est_y / 0.3 m   (the default workspace sector spans
          x 0.18-0.65 m, y +-0.56 m: inputs within about +-2)
    2-3   cos(n yaw), sin(n yaw)   yaw of the estimated hole, n = the shape's rotational symmetry
                                   (constants.SYMMETRY; circle 0, i.e. the constant (1, 0))
    4-6   one-hot shape            circle, square, triangle (the paper's; other shapes: zeros)
    7     (S - 0.05 m) / 0.01 m    characteristic size: 25 mm -> -2.5, 50 mm -> 0, 60 mm -> 1

`geometry`, 9 numbers that describe any part, so that an unseen one is an input the policy reads:

    0-3   as `names`
    4     1 / n                    0 for the circle, square 0.25, hexagon 0.17, rectangle 0.5
    5     (r_in - 0.025 m) / 0.01 m     the peg's inradius (constants.INRADIUS x S; the round
                                        peg's D/2): 10-80 mm parts -> -2.25..1.5
    6     (r_out - 0.025 m) / 0.01 m    its circumradius (constants.CIRCUMRADIUS x S): -2..2.1
    7     (hole_scale - 1) r_in / 1 mm  the radial clearance, hole inradius - peg inradius: the
                                        paper's 50 mm circle 0.75, square 2; tight fits 0.05-0.8
    8     depth / 0.08 m                the hole's depth (constants.HOLE_DEPTH: 1 for every part)

Features 0-3 (`POSE_FEATURES`) are the estimated hole's pose; the rest describe the part. A
policy's manifest may record the range of its training parts' features (`part_range`); the policy
then holds each part feature of a part outside it to that range (`clip_part`: a 10 mm circle reads
as the 50 mm circle for a policy trained on 50 mm parts), since a network's answer for a part
feature it never saw vary is an extrapolation: the shipped `paper`, trained on 50 mm parts alone,
asks k_theta 629 N m/rad for the 50 mm circle and 286 for an 80 mm one.

Encoding the yaw at the shape's symmetry makes poses that are physically the same (a square
turned by 90 deg) the same input, and keeps the input continuous where the board yaw wraps.

Written over the array-API namespace of the inputs (NumPy on the robot, jax.numpy in training);
imports neither numpy nor jax at module level.
"""

from __future__ import annotations

from mjx_peg.array_api import namespace_of
from mjx_peg.errors import UsageError
from mjx_peg.world.constants import (
    CIRCUMRADIUS,
    HOLE_DEPTH,
    INRADIUS,
    PAPER_SHAPES,
    SHAPES,
    SYMMETRY,
)

WORKSPACE_CENTRE = (0.4, 0.0)  # m
POSITION_SCALE = 0.3  # m
SIZE_CENTRE = 0.05  # m, the training size
SIZE_SCALE = 0.01  # m
RADIUS_CENTRE = 0.025  # m, the 50 mm circle's radius
RADIUS_SCALE = 0.01  # m
CLEARANCE_SCALE = 0.001  # m
DEPTH_SCALE = 0.08  # m, the paper's hole depth

OBS_NAMES: tuple[str, ...] = (
    "hole_x",
    "hole_y",
    "cos_n_yaw",
    "sin_n_yaw",
    "is_circle",
    "is_square",
    "is_triangle",
    "size",
)
OBS_SIZE = len(OBS_NAMES)
GEOMETRY_NAMES: tuple[str, ...] = (
    "hole_x",
    "hole_y",
    "cos_n_yaw",
    "sin_n_yaw",
    "inverse_symmetry",
    "peg_inradius",
    "peg_circumradius",
    "radial_clearance",
    "hole_depth",
)
# The observation layouts by name: the features' names, in order. Manifests without a layout
# (every policy exported before the geometry layout) are "names" (file_versions).
LAYOUTS: dict[str, tuple[str, ...]] = {"names": OBS_NAMES, "geometry": GEOMETRY_NAMES}
DEFAULT_LAYOUT = "geometry"  # new training runs'


POSE_FEATURES = 4  # features 0-3 of both layouts: the estimated hole's pose, never clipped


def check_layout(layout: str) -> str:
    """`layout` if it names a layout, else UsageError naming the layouts."""
    if layout not in LAYOUTS:
        raise UsageError(f"unknown observation layout {layout!r}: choose from {', '.join(LAYOUTS)}")
    return layout


def _pose(shape_id, hole_est_pos, hole_est_yaw, dtype, xp):
    """(..., 4) hole x, y and the yaw at the shape's symmetry (features 0-3 of both layouts)."""
    order = xp.asarray(SYMMETRY, dtype=dtype)[shape_id]
    angle = order * xp.asarray(hole_est_yaw, dtype=dtype)
    centre = xp.asarray(WORKSPACE_CENTRE, dtype=dtype)
    return xp.concat(
        [
            (hole_est_pos - centre) / POSITION_SCALE,
            xp.stack([xp.cos(angle), xp.sin(angle)], axis=-1),
        ],
        axis=-1,
    )


def observe(shape_id, size, hole_est_pos, hole_est_yaw):
    """(..., 8) `names` observation from (...,) shape ids, sizes (m), (..., 2) positions, yaws."""
    xp = namespace_of(size, hole_est_pos, hole_est_yaw)
    dtype = hole_est_pos.dtype
    shape_id = xp.asarray(shape_id)
    one_hot = xp.stack([shape_id == i for i in range(len(PAPER_SHAPES))], axis=-1)
    return xp.concat(
        [
            _pose(shape_id, hole_est_pos, hole_est_yaw, dtype, xp),
            xp.astype(one_hot, dtype),
            ((xp.asarray(size, dtype=dtype) - SIZE_CENTRE) / SIZE_SCALE)[..., None],
        ],
        axis=-1,
    )


def observe_geometry(shape_id, size, hole_scale, hole_est_pos, hole_est_yaw):
    """(..., 9) `geometry` observation from (...,) shape ids, sizes S (m), hole scales (hole
    size / peg size), (..., 2) positions and (...,) yaws of the estimated hole."""
    xp = namespace_of(size, hole_scale, hole_est_pos, hole_est_yaw)
    dtype = hole_est_pos.dtype
    shape_id = xp.asarray(shape_id)
    size = xp.asarray(size, dtype=dtype)
    order = xp.asarray(SYMMETRY, dtype=dtype)[shape_id]
    inverse = xp.where(order > 0, 1.0 / xp.where(order > 0, order, 1.0), 0.0)
    r_in = xp.asarray([INRADIUS[s] for s in SHAPES], dtype=dtype)[shape_id] * size
    r_out = xp.asarray([CIRCUMRADIUS[s] for s in SHAPES], dtype=dtype)[shape_id] * size
    clearance = (xp.asarray(hole_scale, dtype=dtype) - 1.0) * r_in
    depth = xp.full(size.shape, HOLE_DEPTH / DEPTH_SCALE, dtype=dtype)
    return xp.concat(
        [
            _pose(shape_id, hole_est_pos, hole_est_yaw, dtype, xp),
            xp.stack(
                [
                    inverse,
                    (r_in - RADIUS_CENTRE) / RADIUS_SCALE,
                    (r_out - RADIUS_CENTRE) / RADIUS_SCALE,
                    clearance / CLEARANCE_SCALE,
                    depth,
                ],
                axis=-1,
            ),
        ],
        axis=-1,
    )


def observe_part(layout: str, shape_id, size, hole_scale, hole_est_pos, hole_est_yaw):
    """(..., len(LAYOUTS[layout])) observation of a part and its estimated hole in `layout`."""
    if check_layout(layout) == "names":
        return observe(shape_id, size, hole_est_pos, hole_est_yaw)
    return observe_geometry(shape_id, size, hole_scale, hole_est_pos, hole_est_yaw)


def part_features(layout: str, shape_id, size, hole_scale):
    """(..., len(LAYOUTS[layout]) - POSE_FEATURES) the features of (...,) parts (shape ids, sizes
    S in m, hole scales) in `layout`, the hole's pose left out."""
    xp = namespace_of(size, hole_scale)
    size = xp.asarray(size)
    zeros = xp.zeros(size.shape, dtype=size.dtype)
    pos = xp.stack([zeros, zeros], axis=-1)
    return observe_part(layout, shape_id, size, hole_scale, pos, zeros)[..., POSE_FEATURES:]


def part_range(layout: str, shape_id, size, hole_scale):
    """(2, k) the lowest and highest value of each part feature over (B,) parts: the range a
    policy trained on them has seen (each feature is monotonic in S and in the hole scale, so the
    corners of a part family's sizes and clearances span it)."""
    xp = namespace_of(size, hole_scale)
    features = part_features(layout, shape_id, size, hole_scale)
    return xp.stack([xp.min(features, axis=0), xp.max(features, axis=0)])


def clip_part(obs, low, high):
    """`obs` (..., n) with its part features (POSE_FEATURES onwards) clipped to [low, high] (each
    (n - POSE_FEATURES,)), in `obs`'s dtype; the hole's pose passes unchanged."""
    xp = namespace_of(obs)
    low, high = (xp.asarray(bound, dtype=obs.dtype) for bound in (low, high))
    part = xp.clip(obs[..., POSE_FEATURES:], low, high)
    return xp.concat([obs[..., :POSE_FEATURES], part], axis=-1)


def observe_specs(specs, layout: str = "names"):
    """(B, n) NumPy observation of a `task.TrialSpec` in `layout` (default: the shipped
    policies' `names`)."""
    return observe_part(layout, specs.shape_id, specs.size, specs.hole_scale, specs.hole_est_pos,
                        specs.hole_est_yaw)  # fmt: skip


# What the critic also sees in training (never the policy, never the robot): the trial's true
# errors and friction, which decide most of a trial's outcome. A value baseline that knows them
# removes that spread from the advantages (an asymmetric actor-critic), so the policy gradient
# sees the effect of its 38 numbers rather than the luck of the draw.
PRIVILEGED_NAMES: tuple[str, ...] = (
    "loc_dx",
    "loc_dy",
    "loc_dyaw",
    "grasp_dz",
    "grasp_tilt_x",
    "grasp_tilt_y",
    "lateral_error",
    "friction",
)
LINEAR_SCALE = 0.008  # m, the paper's largest linear error range
ANGULAR_SCALE = 0.2  # rad, about its 12 deg angular range


def privileged(loc_error, grasp_error, friction):
    """(..., 8) critic-only features from the true (..., 3) errors and (...,) friction."""
    xp = namespace_of(loc_error, grasp_error, friction)
    scale = xp.asarray([LINEAR_SCALE, LINEAR_SCALE, ANGULAR_SCALE], dtype=loc_error.dtype)
    grasp_scale = xp.asarray([LINEAR_SCALE, ANGULAR_SCALE, ANGULAR_SCALE], dtype=loc_error.dtype)
    lateral = xp.linalg.vector_norm(loc_error[..., :2], axis=-1) / LINEAR_SCALE
    return xp.concat(
        [
            loc_error / scale,
            grasp_error / grasp_scale,
            lateral[..., None],
            ((friction - 0.55) / 0.35)[..., None],
        ],
        axis=-1,
    )


def privileged_specs(specs):
    """(B, 8) NumPy critic-only features of a `task.TrialSpec`; its grasp errors wherever the
    trial applied them (the peg's pose in the flange, or the board's height and tilt)."""
    xp = namespace_of(specs.grasp_error)
    board = xp.concat([specs.board_height[:, None], specs.board_tilt], axis=1)
    return privileged(specs.loc_error, specs.grasp_error + board, specs.friction)
