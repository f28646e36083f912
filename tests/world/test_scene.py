"""world/scene.py: the fields each trial overwrites in the compiled scene (board pose, grasp,
friction), and a tilted, raised board's pivot at its hole's entrance."""

import math

import mujoco
import numpy as np

from mjx_peg.world import constants, scene


def rot_z(a):
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def test_board_pose_grasp_and_friction_edits():
    model = scene.load_model("triangle", 0.05)
    ids = scene.scene_ids(model)
    scene.set_board_pose(model, 0.5, -0.2, 0.7)
    scene.set_grasp(model, 0.004, 0.05, -0.08)
    scene.set_friction(model, 0.37)
    data = mujoco.MjData(model)
    data.qpos[ids.qpos_adr] = [3.0, -1.4, 1.5, -1.6, -1.5, 0.3]
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.xpos[ids.board_body], [0.5, -0.2, 0.0], atol=1e-12)
    np.testing.assert_allclose(data.xmat[ids.board_body].reshape(3, 3), rot_z(0.7), atol=1e-12)
    # Peg in the flange frame: (0, 0, dz), R = Ry(tilt_y) Rx(tilt_x).
    f_pos, f_rot = data.site_xpos[ids.flange_site], data.site_xmat[ids.flange_site].reshape(3, 3)
    rel_pos = f_rot.T @ (data.xpos[ids.peg_body] - f_pos)
    rel_rot = f_rot.T @ data.xmat[ids.peg_body].reshape(3, 3)
    cx, sx, cy, sy = math.cos(0.05), math.sin(0.05), math.cos(-0.08), math.sin(-0.08)
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    np.testing.assert_allclose(rel_pos, [0, 0, 0.004], atol=1e-12)
    np.testing.assert_allclose(rel_rot, ry @ rx, atol=1e-12)
    np.testing.assert_allclose(
        model.geom_friction[np.concatenate([ids.peg_geoms, ids.board_geoms]), 0], 0.37
    )
    # The tcp stays nominal; the tip follows the peg.
    tip = (
        data.xpos[ids.peg_body] + data.xmat[ids.peg_body].reshape(3, 3)[:, 2] * constants.PEG_LENGTH
    )
    np.testing.assert_allclose(data.site_xpos[ids.tip_site], tip, atol=1e-12)


def test_a_tilted_raised_board_pivots_about_its_hole_entrance():
    """The paper's grasp errors on the board: the hole's entrance centre stays at (x, y) and
    rises by the height error; the hole axis is the board's tilted z; flat, the pose is exact."""
    from mjx_peg.world.task import board_pose

    model = scene.load_model("square", 0.05)
    ids = scene.scene_ids(model)
    scene.set_board_pose(model, 0.5, -0.2, 0.7, 0.003, (0.08, -0.05))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rot = data.xmat[ids.board_body].reshape(3, 3)
    entrance = data.xpos[ids.board_body] + rot[:, 2] * constants.HOLE_DEPTH
    np.testing.assert_allclose(entrance, [0.5, -0.2, constants.HOLE_DEPTH + 0.003], atol=1e-12)
    cx, sx, cy, sy = math.cos(0.08), math.sin(0.08), math.cos(-0.05), math.sin(-0.05)
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    np.testing.assert_allclose(rot, ry @ rx @ rot_z(0.7), atol=1e-12)
    pos, quat = board_pose(np.array([0.5, -0.2]), np.array(0.7), np.array(0.0), np.zeros(2))
    assert pos.tolist() == [0.5, -0.2, 0.0]
    assert quat.tolist() == [math.cos(0.35), 0.0, 0.0, math.sin(0.35)]
