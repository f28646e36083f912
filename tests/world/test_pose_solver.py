"""world/pose_solver.py: the damped least-squares solve puts a site at a reachable pose."""

import mujoco
import numpy as np
import pytest

from mjx_peg.world import constants, pose_solver, scene
from mjx_peg.world.rotations import tool_down_rotation


@pytest.mark.parametrize("site", ["tcp", "flange"])
def test_a_site_reaches_poses_tool_down_over_the_workspace(site):
    model = scene.load_model("square", 0.05)
    ids = scene.scene_ids(model)
    site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    rng = np.random.default_rng(5)
    data = mujoco.MjData(model)
    for _ in range(5):
        pos = np.array([rng.uniform(0.35, 0.6), rng.uniform(-0.25, 0.25), rng.uniform(0.2, 0.4)])
        rot = tool_down_rotation(rng.uniform(-np.pi, np.pi))
        data.qpos[ids.qpos_adr] = pose_solver.solve_site_pose(model, pos, rot, site=site)
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(data.site_xpos[site_id], pos, atol=1e-9)
        np.testing.assert_allclose(data.site_xmat[site_id].reshape(3, 3), rot, atol=1e-9)
    with pytest.raises(KeyError, match="no site named 'nozzle'"):
        pose_solver.solve_site_pose(model, pos, rot, site="nozzle")


def test_the_demo_pose_holds_the_tip_over_the_hole():
    model = scene.load_model("circle", 0.05)
    ids = scene.scene_ids(model)
    data = pose_solver.demo_pose(model, board_xy=(0.5, -0.1), board_yaw=0.4, tip_above=0.03)
    expected = (0.5, -0.1, constants.HOLE_DEPTH + 0.03)
    np.testing.assert_allclose(data.site_xpos[ids.tcp_site], expected, atol=1e-9)
    np.testing.assert_allclose(data.xpos[ids.board_body], [0.5, -0.1, 0.0], atol=1e-12)
