"""The family of parts: each part's hole is its peg's section scaled by its clearance, built of
boxes that enclose it; the peg passes it straight and touches a wall just beyond its clearance."""

import math

import mujoco
import numpy as np
import pytest

from mjx_peg.world import constants, mjcf, parts, pose_solver, scene
from mjx_peg.world.rotations import tool_down_rotation

# Every part of the family at the ends and middle of its sizes, at the paper's and tight fits.
PARTS = [
    (shape, mm, fit)
    for shape in constants.SHAPES
    for mm in (10, 50, 80)
    for fit in ("paper", "tight")
]


def rot_z(a):
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def place_tool_down(model, tcp_pos, yaw):
    """MjData with the arm's tcp at `tcp_pos`, tool pointing down at `yaw` (mj_forward done)."""
    ids = scene.scene_ids(model)
    data = mujoco.MjData(model)
    data.qpos[ids.qpos_adr] = pose_solver.solve_site_pose(model, tcp_pos, tool_down_rotation(yaw))
    mujoco.mj_forward(model, data)
    assert np.linalg.norm(data.site_xpos[ids.tcp_site] - tcp_pos) < 1e-9
    return data


def board_contacts(model, data):
    board = set(scene.board_geom_ids(model).tolist())
    return [i for i in range(data.ncon) if {data.contact.geom1[i], data.contact.geom2[i]} & board]


def polygon_distance(walls, angle):
    """Distance (m) from the axis along `angle` (board frame) to the hole's boundary: the
    nearest wall line the ray meets (walls: (normal angle, distance) pairs)."""
    c = np.cos(angle - walls[:, 0])
    return np.min(np.where(c > 1e-12, walls[:, 1] / np.where(c > 1e-12, c, 1.0), np.inf))


@pytest.mark.parametrize(("shape", "mm", "fit"), PARTS)
def test_hole_measured_by_rays_is_the_part_scaled(shape, mm, fit):
    """Rays from the hole axis meet the walls where the hole polygon (the peg's section scaled by
    the part's hole scale) is: its inradius and circumradius are constants.INRADIUS and
    CIRCUMRADIUS x hole_scale x S, its first edge along board x on the -y side; the hole runs
    through and the board top is solid from the hole's corners out to 0.1 m."""
    size, scale = mm / 1000, constants.HOLE_FITS[fit][shape]
    model = scene.load_model(shape, size, scale)
    walls = np.array(parts.hole_walls(shape, size, scale))
    n = constants.HOLE_SIDES[shape]
    assert len(walls) == n == len(scene.board_geom_ids(model))
    np.testing.assert_allclose(walls[:, 0], -np.pi / 2 + 2 * np.pi * np.arange(n) / n)
    rng = np.random.default_rng(mm)
    x, y, yaw = 0.3 + 0.3 * rng.random(), -0.3 + 0.6 * rng.random(), rng.uniform(0, np.pi / 2)
    scene.set_board_pose(model, x, y, yaw)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    board = set(scene.board_geom_ids(model).tolist())
    board_only = np.array([0, 1, 0, 0, 0, 0], dtype=np.uint8)  # geom group 1 = board walls
    geomid = np.zeros(1, dtype=np.int32)

    def ray(origin, board_angle):
        a = yaw + board_angle
        hit = mujoco.mj_ray(model, data, origin, np.array([math.cos(a), math.sin(a), 0.0]),
                            board_only, 1, -1, geomid)  # fmt: skip
        assert geomid[0] in board
        return hit

    corners = parts.hole_corners(shape, size, scale)
    corner_angles = np.arctan2(corners[:, 1], corners[:, 0])
    for z in (0.002, constants.HOLE_DEPTH / 2, constants.HOLE_DEPTH - 0.002):
        origin = np.array([x, y, z])
        for a in np.linspace(0, 2 * np.pi, 360, endpoint=False):
            assert ray(origin, a) == pytest.approx(polygon_distance(walls, a), abs=1e-9)
        along_normals = [ray(origin, phi) for phi in walls[:, 0]]
        np.testing.assert_allclose(along_normals, walls[:, 1], atol=1e-9)
        assert min(along_normals) == pytest.approx(scale * constants.INRADIUS[shape] * size)
        to_corners = [ray(origin, a) for a in corner_angles]
        np.testing.assert_allclose(to_corners, np.linalg.norm(corners, axis=1), atol=1e-7)
    if shape != "circle":  # the round hole is a polygon around the circle of hole_scale D
        r_out = np.linalg.norm(corners, axis=1).max()
        assert r_out == pytest.approx(scale * constants.CIRCUMRADIUS[shape] * size)
    if shape == "triangle":  # the corner opposite the -y edge is on +y
        assert corner_angles[np.argmax(corners[:, 1])] == pytest.approx(np.pi / 2)
    # Through hole: a ray down the axis from above the board meets no wall.
    down = np.array([0, 0, -1.0])
    assert mujoco.mj_ray(model, data, np.array([x, y, 0.2]), down, board_only, 1, -1, geomid) == -1
    # No gaps: the board top (z = HOLE_DEPTH) is solid from the hole's corners out to 0.1 m.
    r_corner = np.linalg.norm(corners, axis=1).max()
    assert mjcf.board_half_width(shape, size, scale) >= max(0.1, walls[:, 1].max() + 0.05)
    for _ in range(200):
        a, rho = rng.uniform(0, 2 * np.pi), rng.uniform(r_corner + 1e-4, mjcf.BOARD_MIN_HALF_WIDTH)
        start = np.array([x + rho * math.cos(a), y + rho * math.sin(a), 0.2])
        hit = mujoco.mj_ray(model, data, start, down, board_only, 1, -1, geomid)
        assert hit == pytest.approx(0.2 - constants.HOLE_DEPTH, abs=1e-9), (a, rho)


def travel(walls, peg, direction):
    """How far (m) the peg's section `peg` (n, 2), centred on the axis, moves along `direction`
    before it meets a wall: the least gap, wall distance less the peg's reach along its normal,
    over the wall's share of the direction."""
    normals = np.stack([np.cos(walls[:, 0]), np.sin(walls[:, 0])], axis=-1)
    gaps = walls[:, 1] - np.max(peg @ normals.T, axis=0)
    share = normals @ direction
    return float(np.min(gaps[share > 1e-12] / share[share > 1e-12]))


@pytest.mark.parametrize(("shape", "mm", "fit"), PARTS)
def test_every_part_passes_its_hole_and_touches_just_beyond_its_clearance(shape, mm, fit):
    """Zero errors: the peg (its section seen tool-down, y mirrored) slides down the hole axis
    to 20 mm above the table touching nothing; moved across along board +-x or +-y by its
    clearance that way less 0.2 mm it still touches nothing, by 0.2 mm more it touches a wall."""
    size, scale = mm / 1000, constants.HOLE_FITS[fit][shape]
    model = scene.load_model(shape, size, scale)
    yaw = 0.4
    data = place_tool_down(model, (0.5, -0.05, 0.35), yaw)
    ids = scene.scene_ids(model)
    tip = data.site_xpos[ids.tip_site].copy()
    board = ids.board_body
    peg = parts.peg_section(shape, size) * np.array([1.0, -1.0])  # in the board frame
    walls = np.array(parts.hole_walls(shape, size, scale))

    def probe(h, peg_offset=(0.0, 0.0)):
        """Board contacts with the tip h above the board-frame table, moved across the hole."""
        off = rot_z(yaw) @ np.array([*peg_offset, 0.0])
        model.body_pos[board] = tip - np.array([0, 0, h]) - off
        model.body_quat[board] = (math.cos(yaw / 2), 0, 0, math.sin(yaw / 2))
        mujoco.mj_forward(model, data)
        return board_contacts(model, data)

    for h in np.arange(0.16, 0.0199, -0.01):
        assert probe(h) == [], f"contact at tip height {h:.3f}"
    for u in np.array([(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]):
        clearance = travel(walls, peg, u)
        assert clearance > 0.0
        if clearance > 2e-4:
            assert probe(0.02, u * (clearance - 2e-4)) == [], u
        assert probe(0.02, u * (clearance + 2e-4)), u


@pytest.mark.parametrize(
    "shape, corners",
    [  # peg frame, counter-clockwise, in units of S
        ("square", [(0.5, 0.5), (-0.5, 0.5), (-0.5, -0.5), (0.5, -0.5)]),
        ("rectangle", [(0.5, -0.25), (0.5, 0.25), (-0.5, 0.25), (-0.5, -0.25)]),
        ("hexagon", [(1 / math.sqrt(3) * math.cos(a), 1 / math.sqrt(3) * math.sin(a))
                     for a in np.radians([0, 60, 120, 180, 240, 300])]),
        ("triangle", [(0.0, -1 / math.sqrt(3)), (0.5, 0.5 / math.sqrt(3)),
                      (-0.5, 0.5 / math.sqrt(3))]),
    ],
)  # fmt: skip
def test_peg_sections_are_their_shapes(shape, corners):
    np.testing.assert_allclose(parts.peg_section(shape, 0.04), 0.04 * np.array(corners), atol=1e-15)
    round_peg = parts.peg_section("circle", 0.04)
    assert len(round_peg) == constants.CIRCLE_SIDES
    np.testing.assert_allclose(np.linalg.norm(round_peg, axis=1), 0.02)


def test_the_paper_fits_are_the_default_and_others_are_checked():
    for shape in constants.SHAPES:
        assert parts.check_hole_scale(shape) == constants.HOLE_SCALE[shape]
        assert parts.hole_walls(shape, 0.05) == parts.hole_walls(
            shape, 0.05, constants.HOLE_SCALE[shape]
        )
    for bad in (1.0, 1.3, float("nan"), "tight"):
        with pytest.raises(ValueError, match=r"hole scale .* must be a number in \[1.01, 1.25\]"):
            parts.check_hole_scale("square", bad)
    with pytest.raises(ValueError, match="unknown shape 'octagon'"):
        parts.hole_walls("octagon", 0.05)
    assert mjcf.build_mjcf("square", 0.05) == mjcf.build_mjcf("square", 0.05, 1.08)
    assert 'model="mjx_peg_square_50mm_hole1.02"' in mjcf.build_mjcf("square", 0.05, 1.02)


def test_hole_scales_parse_from_fits_numbers_and_ranges():
    assert parts.hole_scale_ranges(None) == () and parts.hole_scale_ranges({"square": 1.05}) == (
        ("square", 1.05, 1.05),
    )
    assert parts.hole_scale_ranges("tight")[0] == ("circle", 1.01, 1.01)
    np.testing.assert_allclose(
        parts.hole_scale_values(1.01, 1.03), [1.01, 1.015, 1.02, 1.025, 1.03]
    )
    assert (
        parts.hole_scale_of("hexagon", "tight") == 1.02
        and parts.hole_scale_of("circle", None) == 1.03
    )
    assert parts.parse_hole_scale("tight") == "tight" and parts.parse_hole_scale("1.04") == 1.04
    for text in ("loose", "1.0", "2", "nan"):
        with pytest.raises(ValueError, match="--hole-scale must be paper or tight or a number"):
            parts.parse_hole_scale(text)
    with pytest.raises(ValueError, match="hole scale 'tight'|no single value"):
        parts.hole_scale_of("square", (1.02, 1.08))


@pytest.mark.parametrize("shape", ["hexagon", "rectangle"])
def test_the_baseline_inserts_a_new_part_from_zero_error(shape):
    """The hand-tuned numbers with the spiral skill on the C engine: a 50 mm hexagon or
    rectangle peg at its paper and tight fits, no error, is in within 4 s of simulated time."""
    from mjx_peg.engines import run_trials
    from mjx_peg.engines.trial import TrialConfig
    from mjx_peg.skill.baseline import baseline_params
    from mjx_peg.skill.search import skill_config
    from mjx_peg.world.task import TaskConfig, TrialSpec, sample_trials

    specs = TrialSpec.concat([
        sample_trials(TaskConfig(shapes=(shape,), linear_error=0.0, angular_error=0.0,
                                 hole_scale=fit), 7, 2)
        for fit in ("paper", "tight")
    ])  # fmt: skip
    np.testing.assert_array_equal(specs.hole_scale, [1.08, 1.08, 1.02, 1.02])
    config = TrialConfig(time_limit_s=4.0, search=skill_config("spiral"))
    result = run_trials(specs, baseline_params(), "mujoco", config, threads=1)
    assert result.success.all(), result.time_s
