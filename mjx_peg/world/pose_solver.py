"""An arm configuration that puts a site at a pose: damped least squares on MuJoCo's Jacobian.

For rendering and tests (a demo pose, a tip above a hole); the engines and the robot use the
UR5e's closed-form kinematics (`kinematics.py`). Each iteration solves

    dq = J^T (J J^T + lambda I)^-1 e,   e = [p* - p, log(R* R^T)]   (6-D pose error, world frame)

and takes dq scaled so that no joint moves more than 0.5 rad, until |e| < 1e-12.
"""

from __future__ import annotations

from mjx_peg.world import gl

gl.choose_backend()

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from mjx_peg.world import scene  # noqa: E402
from mjx_peg.world.constants import HOLE_DEPTH, HOME_Q  # noqa: E402
from mjx_peg.world.rotations import tool_down_rotation  # noqa: E402


def solve_site_pose(
    model: mujoco.MjModel,
    pos,
    rot,
    site: str = "tcp",
    q_init=HOME_Q,
    iterations: int = 100,
    damping: float = 1e-4,
) -> np.ndarray:
    """(6,) arm configuration putting `site` at world `pos` with world rotation `rot` (3, 3).

    Damped least squares on the site's 6-D Jacobian from `q_init` (default: elbow up, tool down,
    facing +x). A convenience for rendering and tests; the engines use kinematics.py.
    """
    ids = scene.scene_ids(model)
    site_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    if site_id < 0:
        raise KeyError(f"the model has no site named {site!r}")
    data = mujoco.MjData(model)
    q = np.array(q_init, dtype=np.float64)
    pos = np.asarray(pos, dtype=np.float64)
    rot = np.asarray(rot, dtype=np.float64)
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for _ in range(iterations):
        data.qpos[ids.qpos_adr] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        cur = data.site_xmat[site_id].reshape(3, 3)
        err_r = rot @ cur.T
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, err_r.ravel())
        err_w = np.zeros(3)
        mujoco.mju_quat2Vel(err_w, quat, 1.0)
        err = np.concatenate([pos - data.site_xpos[site_id], err_w])
        if np.linalg.norm(err) < 1e-12:
            break
        mujoco.mj_jacSite(model, data, jp, jr, site_id)
        jac = np.concatenate([jp, jr])[:, ids.dof_adr]
        step = jac.T @ np.linalg.solve(jac @ jac.T + damping * np.eye(6), err)
        q = q + step * min(1.0, 0.5 / max(np.abs(step).max(), 1e-12))
    return q


def demo_pose(
    model: mujoco.MjModel, board_xy=(0.45, 0.1), board_yaw=0.3, tip_above=0.05
) -> mujoco.MjData:
    """MjData: board at `board_xy`, `board_yaw`; tool down, peg tip `tip_above` m over the hole."""
    scene.set_board_pose(model, board_xy[0], board_xy[1], board_yaw)
    target = (board_xy[0], board_xy[1], HOLE_DEPTH + tip_above)
    q = solve_site_pose(model, target, tool_down_rotation(board_yaw))
    data = mujoco.MjData(model)
    data.qpos[scene.scene_ids(model).qpos_adr] = q
    mujoco.mj_forward(model, data)
    return data
