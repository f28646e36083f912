"""The compiled scene of one part (shape, size, hole scale) and the fields each trial overwrites.

The MJCF is `mjcf.build_mjcf`'s (frames, names and units: CONVENTIONS.md). A trial changes only
model fields, never the model's structure, so one compiled model per part (shape, size S, hole
scale) serves every trial of that part (`load_model`, cached, an independent copy per call):

    board:     body_pos[board], body_quat[board]   yaw about z, then the tilt about the hole's
                                                   entrance (`task.board_pose`)
    grasp:     body_pos[peg] = (0, 0, dz), body_quat[peg] = Ry(tilt_y) Rx(tilt_x)
    friction:  geom_friction[peg and board geoms, 0] = mu (the table keeps its own)

The MJX engine writes the same fields into its batched model. `start_trial` then puts the arm at
rest at q0, held still by gravity compensation u = h = qfrc_bias - qfrc_passive.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math

from mjx_peg.world import gl

gl.choose_backend()

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from mjx_peg.world.constants import ACTUATOR_NAMES, JOINT_NAMES  # noqa: E402
from mjx_peg.world.mjcf import WRIST3_BODY, build_mjcf  # noqa: E402
from mjx_peg.world.parts import check_hole_scale, check_part  # noqa: E402
from mjx_peg.world.task import board_pose  # noqa: E402


@functools.lru_cache(maxsize=64)  # a few dozen parts at most
def _compiled(shape: str, size: float, hole_scale: float) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(build_mjcf(shape, size, hole_scale))


def load_model(shape: str, size: float, hole_scale: float | None = None) -> mujoco.MjModel:
    """The compiled scene for (shape, size in m, hole scale: hole size / peg size, None for the
    shape's paper fit).

    Compilation is cached per part (functools.lru_cache); every call returns an independent copy,
    so callers may overwrite board pose, grasp and friction freely.
    """
    shape, size = check_part(shape, size)
    return copy.deepcopy(_compiled(shape, size, check_hole_scale(shape, hole_scale)))


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    idx = mujoco.mj_name2id(model, kind, name)
    if idx < 0:
        raise KeyError(f"the model has no {kind.name[6:].lower()} named {name!r}")
    return int(idx)


def set_board_pose(
    model: mujoco.MjModel, x: float, y: float, yaw: float, height: float = 0.0, tilt=(0.0, 0.0)
) -> None:
    """Place the board: yaw about world z, then `tilt` (x, y) about its hole's entrance centre,
    which sits at (x, y, HOLE_DEPTH + height) (`task.board_pose`); flat: body_pos = (x, y, 0)."""
    b = _id(model, mujoco.mjtObj.mjOBJ_BODY, "board")
    model.body_pos[b], model.body_quat[b] = board_pose((x, y), yaw, height, tilt)


def grasp_quat(tilt_x: float, tilt_y: float) -> np.ndarray:
    """(4,) quaternion (w, x, y, z) of the peg in the flange frame for a tilted grasp.

    A rotation about the flange x axis by tilt_x, then about the (fixed) flange y axis by tilt_y:
    R = Ry(tilt_y) Rx(tilt_x).
    """
    cx, sx = math.cos(0.5 * tilt_x), math.sin(0.5 * tilt_x)
    cy, sy = math.cos(0.5 * tilt_y), math.sin(0.5 * tilt_y)
    # (cy, 0, sy, 0) * (cx, sx, 0, 0)
    return np.array([cy * cx, cy * sx, sy * cx, -sy * sx])


def set_grasp(model: mujoco.MjModel, dz: float, tilt_x: float, tilt_y: float) -> None:
    """Grasp error: peg body pos (0, 0, dz), quat grasp_quat(tilt_x, tilt_y) (flange frame)."""
    p = _id(model, mujoco.mjtObj.mjOBJ_BODY, "peg")
    model.body_pos[p] = (0.0, 0.0, dz)
    model.body_quat[p] = grasp_quat(tilt_x, tilt_y)


def peg_geom_ids(model: mujoco.MjModel) -> np.ndarray:
    """Ids of the peg's collision geoms (those of body `peg`)."""
    p = _id(model, mujoco.mjtObj.mjOBJ_BODY, "peg")
    return np.flatnonzero(model.geom_bodyid == p)


def board_geom_ids(model: mujoco.MjModel) -> np.ndarray:
    """Ids of the board's collision geoms (the hole's wall boxes, body `board`)."""
    b = _id(model, mujoco.mjtObj.mjOBJ_BODY, "board")
    return np.flatnonzero(model.geom_bodyid == b)


def set_friction(model: mujoco.MjModel, mu: float) -> None:
    """Peg-board sliding friction: geom_friction[:, 0] = mu on every peg and board geom."""
    ids = np.concatenate([peg_geom_ids(model), board_geom_ids(model)])
    model.geom_friction[ids, 0] = mu


def bias_torque(qfrc_bias, qfrc_passive, dof_adr):
    """(..., 6) h of the arm's joints: Coriolis, centrifugal and gravity torques less the passive
    (joint damping) ones; `ctrl = h` holds an arm at rest still. NumPy (MjData) or JAX (MJX)."""
    return qfrc_bias[..., dof_adr] - qfrc_passive[..., dof_adr]


def start_trial(specs, index: int, model, data, ids) -> None:
    """Set up trial `index` of `specs` in `model`/`data`: board pose, grasp error, friction, the
    arm at rest at q0 and held still by gravity compensation in `data.ctrl`; kinematics and
    sensors computed (the F/T reading is then the tare)."""
    board_xy, board_yaw = specs.board_pos[index], specs.board_yaw[index]
    grasp_error, friction, q0 = specs.grasp_error[index], specs.friction[index], specs.q0[index]
    set_board_pose(model, float(board_xy[0]), float(board_xy[1]), float(board_yaw),
                   float(specs.board_height[index]), specs.board_tilt[index])  # fmt: skip
    set_grasp(model, *(float(v) for v in grasp_error))
    set_friction(model, float(friction))
    mujoco.mj_resetData(model, data)
    data.qpos[ids.qpos_adr] = q0
    mujoco.mj_forward(model, data)
    data.ctrl[ids.actuator_ids] = bias_torque(data.qfrc_bias, data.qfrc_passive, ids.dof_adr)
    mujoco.mj_forward(model, data)


@dataclasses.dataclass(frozen=True, eq=False)
class SceneIds:
    """Names resolved to ids/addresses once per compiled scene (arrays follow JOINT_NAMES order)."""

    joint_ids: np.ndarray  # (6,) joint ids
    qpos_adr: np.ndarray  # (6,) qpos addresses of the arm joints
    dof_adr: np.ndarray  # (6,) dof addresses (qvel, qfrc_*) of the arm joints
    actuator_ids: np.ndarray  # (6,) actuator ids (ctrl indices), ACTUATOR_NAMES order
    flange_site: int
    tcp_site: int
    ft_site: int
    tip_site: int  # site `peg_tip`
    wrist3_body: int
    board_body: int
    peg_body: int
    ft_force_adr: int  # sensordata[adr : adr + 3]
    ft_torque_adr: int
    peg_geoms: np.ndarray
    board_geoms: np.ndarray
    table_geom: int
    birdseye_camera: int


def scene_ids(model: mujoco.MjModel) -> SceneIds:
    """Resolve every name the engines need (KeyError naming the missing object)."""
    O = mujoco.mjtObj  # noqa: E741, N806
    joints = np.array([_id(model, O.mjOBJ_JOINT, n) for n in JOINT_NAMES])
    return SceneIds(
        joint_ids=joints,
        qpos_adr=np.array(model.jnt_qposadr[joints]),
        dof_adr=np.array(model.jnt_dofadr[joints]),
        actuator_ids=np.array([_id(model, O.mjOBJ_ACTUATOR, n) for n in ACTUATOR_NAMES]),
        flange_site=_id(model, O.mjOBJ_SITE, "flange"),
        tcp_site=_id(model, O.mjOBJ_SITE, "tcp"),
        ft_site=_id(model, O.mjOBJ_SITE, "ft"),
        tip_site=_id(model, O.mjOBJ_SITE, "peg_tip"),
        wrist3_body=_id(model, O.mjOBJ_BODY, WRIST3_BODY),
        board_body=_id(model, O.mjOBJ_BODY, "board"),
        peg_body=_id(model, O.mjOBJ_BODY, "peg"),
        ft_force_adr=int(model.sensor_adr[_id(model, O.mjOBJ_SENSOR, "ft_force")]),
        ft_torque_adr=int(model.sensor_adr[_id(model, O.mjOBJ_SENSOR, "ft_torque")]),
        peg_geoms=peg_geom_ids(model),
        board_geoms=board_geom_ids(model),
        table_geom=_id(model, O.mjOBJ_GEOM, "table"),
        birdseye_camera=_id(model, O.mjOBJ_CAMERA, "birdseye"),
    )
