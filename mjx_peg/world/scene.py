"""The MJCF scene for one (shape, size): UR5e on a table, a board with a through hole, a peg.

Frames, names and units follow CONVENTIONS.md (SI units inside; the CLI takes mm).

Scene contents
--------------
- The UR5e from ``scenes/ur5e.xml`` (standard DH; the wrist-3 body frame is DH frame 6, and the
  site ``flange`` sits at its origin). The arm makes no contacts and owns the only 6 dofs.
- Table: the plane z = 0 (geom ``table``).
- Board: body ``board``, a *plain fixed body* (no joint, not mocap). Its frame origin is on the
  hole axis at the table top; the board spans 0 <= z <= HOLE_DEPTH in that frame and the hole runs
  through it along z. The engines place it per trial by overwriting ``model.body_pos[board]`` =
  (x, y, 0) and ``model.body_quat[board]`` = yaw about z (``set_board_pose``; the MJX engine writes
  the same two fields into its batched model). The hole is made only of boxes, one per edge of the
  hole polygon: the box's inner face lies on the edge line and the box is long enough to reach the
  neighbouring boxes at the board's outer outline (a polygon with the same edge directions whose
  inradius is ``board_half_width(shape, size)`` >= 0.1 m), so the walls have no gaps; the board
  top is solid at least out to 0.1 m from the hole axis (the triangle's board looks like a
  three-bladed star: the box ends stick out past the outline's corners).
  Hole reference orientation: at board yaw 0 one hole edge is parallel to world x, on the -y side
  of the axis (square: edges along x and y; triangle: an edge along x at y = -r_in with the
  opposite corner on +y; circle: a regular HOLE_SIDES-gon with one edge along x at y = -r_in).
- Peg: body ``peg``, child of the wrist-3 body; its frame has its origin at the grasp point and z
  along the peg away from the flange; it spans 0 <= z <= PEG_LENGTH. The nominal grasp is the
  identity relative to ``flange``; grasp errors overwrite ``body_pos[peg]`` = (0, 0, dz) and
  ``body_quat[peg]`` (``set_grasp``). Square peg: a box of edge L. Circle peg: a convex mesh prism
  with CIRCLE_SIDES sides and circumradius D/2 (MJX has no cylinder-box collision). Triangle peg:
  a convex mesh prism, equilateral with edge L, corners at -90, 30 and 150 deg about the peg z
  axis: with the tool pointing down at the hole's yaw, R = Rz(yaw) Rx(pi), this is the hole's
  triangle (Rx(pi) mirrors y).
- Sites: ``flange`` (wrist-3 origin), ``tcp`` (wrist-3, (0, 0, PEG_LENGTH)), ``ft`` (peg origin),
  ``peg_tip`` (peg, (0, 0, PEG_LENGTH)). Sensors ``ft_force`` and ``ft_torque`` on site ``ft``:
  MuJoCo's force/torque sensors, expressed in the ``ft`` frame; they report the wrench that the
  wrist-3 body exerts on the peg: a peg held still in free space, tool down, reads (0, 0, -m g)
  (m g upward in the world), and after taring, a peg pressed onto a surface with force F along its
  own +z reads (0, 0, +F). The external (contact) wrench on the peg at rest is minus the tared
  reading.
- Contacts: only peg-board and peg-table (peg contype=1 conaffinity=2; board and table contype=2
  conaffinity=1; arm 0/0), condim 3. The pair friction is the max of the two geoms' frictions;
  ``set_friction`` writes the sliding friction of every geom in ``peg_geom_ids`` and
  ``board_geom_ids`` (the table keeps TABLE_FRICTION, so peg-table friction = max(mu, 0.3)).
- Geom groups: 0 table, 1 board walls, 2 arm and peg (all visible by default); sites are group 4.
- Cameras: ``birdseye`` (fixed at (0.35, 0, 1.3) looking straight down, image up = world +x;
  at 4:3 it covers about x in [-0.19, 0.89], y in [-0.72, 0.72]) and ``overview`` (a fixed 3/4
  view of the workspace).

Physics: 2 ms steps, implicitfast, pyramidal cone, Newton solver with 20 iterations and 10 line
search iterations, gravity on.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import pathlib
import xml.etree.ElementTree as ET

from mjx_peg.errors import UsageError
from mjx_peg.world import gl

gl.choose_backend()

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from mjx_peg.world.constants import (  # noqa: E402
    ACTUATOR_NAMES,
    CIRCLE_SIDES,
    HOLE_DEPTH,
    HOLE_SCALE,
    HOLE_SIDES,
    HOME_Q,
    JOINT_NAMES,
    PEG_LENGTH,
    PEG_MASS,
    SHAPES,
    TIMESTEP,
)
from mjx_peg.world.rotations import tool_down_rotation  # noqa: E402
from mjx_peg.world.task import board_pose  # noqa: E402

BOARD_MIN_HALF_WIDTH = 0.1  # m: inradius of the board's outer outline (at least)
BOARD_MIN_WALL = 0.05  # m: wall thickness around the hole (at least)
DEFAULT_FRICTION = 0.5  # peg and board sliding friction until set_friction is called
TABLE_FRICTION = 0.3
WRIST3_BODY = "wrist_3_link"
UR5E_XML = pathlib.Path(__file__).resolve().parents[2] / "scenes" / "ur5e.xml"


def _fmt(x: float) -> str:
    """A float written exactly enough for 1e-12 m / rad."""
    return repr(float(x)) if x != 0.0 else "0"


def _vec(*xs: float) -> str:
    return " ".join(_fmt(x) for x in xs)


def _check(shape: str, size: float) -> tuple[str, float]:
    """Validated (shape, size) or ValueError with one line naming the valid values."""
    if shape not in SHAPES:
        raise UsageError(f"unknown shape {shape!r}: valid shapes are {', '.join(SHAPES)}")
    try:
        size = float(size)
    except (TypeError, ValueError):
        raise UsageError(f"size must be a finite number of metres > 0, got {size!r}") from None
    if not (math.isfinite(size) and size > 0.0):
        raise UsageError(f"size must be a finite number of metres > 0, got {size!r}")
    return shape, size


def hole_inradius(shape: str, size: float) -> float:
    """Hole polygon inradius (m): circle 1.03 D/2, square 1.08 L/2, triangle 1.08 L/(2 sqrt 3)."""
    shape, size = _check(shape, size)
    width = HOLE_SCALE[shape] * size  # circle: inscribed diameter, square/triangle: edge
    return width / (2.0 * math.sqrt(3.0)) if shape == "triangle" else width / 2.0


def hole_normal_angles(shape: str) -> np.ndarray:
    """Angles (rad, board frame) of the hole edges' outward normals; the first is -90 deg."""
    n = HOLE_SIDES[shape]
    return -0.5 * math.pi + 2.0 * math.pi * np.arange(n) / n


def board_half_width(shape: str, size: float) -> float:
    """Inradius (m) of the board's outer outline: max(0.1 m, hole inradius + 0.05 m)."""
    return max(BOARD_MIN_HALF_WIDTH, hole_inradius(shape, size) + BOARD_MIN_WALL)


def peg_section(shape: str, size: float) -> np.ndarray:
    """(n, 2) corners of the peg cross-section in the peg frame (x, y), counter-clockwise."""
    shape, size = _check(shape, size)
    if shape == "circle":
        angles = 2.0 * math.pi * np.arange(CIRCLE_SIDES) / CIRCLE_SIDES
        radius = size / 2.0
    elif shape == "square":
        angles = math.pi / 4 + 0.5 * math.pi * np.arange(4)
        radius = size / math.sqrt(2.0)
    else:
        angles = -0.5 * math.pi + 2.0 * math.pi * np.arange(3) / 3
        radius = size / math.sqrt(3.0)
    return radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def grasp_quat(tilt_x: float, tilt_y: float) -> np.ndarray:
    """(4,) quaternion (w, x, y, z) of the peg in the flange frame for a tilted grasp.

    A rotation about the flange x axis by tilt_x, then about the (fixed) flange y axis by tilt_y:
    R = Ry(tilt_y) Rx(tilt_x).
    """
    cx, sx = math.cos(0.5 * tilt_x), math.sin(0.5 * tilt_x)
    cy, sy = math.cos(0.5 * tilt_y), math.sin(0.5 * tilt_y)
    # (cy, 0, sy, 0) * (cx, sx, 0, 0)
    return np.array([cy * cx, cy * sx, sy * cx, -sy * sx])


def _look_at_xyaxes(eye, target) -> str:
    """MJCF `xyaxes` of a camera at `eye` looking at `target` with world z up in the image."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    return _vec(*right, *up)


def _sub(parent: ET.Element, tag: str, **attrs) -> ET.Element:
    return ET.SubElement(parent, tag, {k: str(v) for k, v in attrs.items()})


def _add_board(worldbody: ET.Element, shape: str, size: float) -> None:
    r = hole_inradius(shape, size)
    w = board_half_width(shape, size)
    n = HOLE_SIDES[shape]
    half_len = w * math.tan(math.pi / n)  # reaches the outer outline's corners
    half_thick = 0.5 * (w - r)
    board = _sub(worldbody, "body", name="board", pos="0.45 0.1 0")
    for k, phi in enumerate(hole_normal_angles(shape)):
        c = r + half_thick
        yaw = phi - 0.5 * math.pi  # box x along the edge, box y along the outward normal
        _sub(
            board,
            "geom",
            name=f"board_wall{k}",
            type="box",
            size=_vec(half_len, half_thick, 0.5 * HOLE_DEPTH),
            pos=_vec(c * math.cos(phi), c * math.sin(phi), 0.5 * HOLE_DEPTH),
            quat=_vec(math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw)),
            material="board",
            contype=2,
            conaffinity=1,
            condim=3,
            group=1,
            friction=_vec(DEFAULT_FRICTION, 0.005, 0.0001),
        )
    _sub(board, "site", name="hole", pos="0 0 0", size="0.005", rgba="0 1 0 1", group=4)


def _add_peg(wrist3: ET.Element, asset: ET.Element, shape: str, size: float) -> None:
    _sub(
        wrist3,
        "site",
        name="tcp",
        pos=_vec(0, 0, PEG_LENGTH),
        size="0.006",
        rgba="0 0.6 1 1",
        group=4,
    )
    peg = _sub(wrist3, "body", name="peg", pos="0 0 0", quat="1 0 0 0")
    radius = size / 2.0
    ixy = PEG_MASS * (3.0 * radius**2 + PEG_LENGTH**2) / 12.0
    izz = PEG_MASS * radius**2 / 2.0
    _sub(
        peg,
        "inertial",
        pos=_vec(0, 0, PEG_LENGTH / 2),
        mass=_fmt(PEG_MASS),
        diaginertia=_vec(ixy, ixy, izz),
    )
    common = dict(
        contype=1,
        conaffinity=2,
        condim=3,
        group=2,
        material="peg",
        friction=_vec(DEFAULT_FRICTION, 0.005, 0.0001),
    )
    if shape == "square":
        box = _vec(size / 2, size / 2, PEG_LENGTH / 2)
        _sub(
            peg, "geom", name="peg", type="box", size=box, pos=_vec(0, 0, PEG_LENGTH / 2), **common
        )
    else:
        corners = peg_section(shape, size)
        verts = [(x, y, z) for z in (0.0, PEG_LENGTH) for x, y in corners]
        _sub(asset, "mesh", name="peg_mesh", vertex=" ".join(_vec(*v) for v in verts))
        _sub(peg, "geom", name="peg", type="mesh", mesh="peg_mesh", **common)
    _sub(peg, "site", name="ft", pos="0 0 0", size="0.008", rgba="1 1 0 1", group=4)
    _sub(
        peg,
        "site",
        name="peg_tip",
        pos=_vec(0, 0, PEG_LENGTH),
        size="0.006",
        rgba="1 0 0 1",
        group=4,
    )


@functools.cache
def _arm_xml() -> str:
    return UR5E_XML.read_text()


def build_mjcf(shape: str, size: float) -> str:
    """The full scene's MJCF (a standalone XML string) for `shape` in SHAPES and `size` in m.

    size is the characteristic size S: circle diameter D, square edge L, triangle edge L.
    Raises ValueError for an unknown shape or a size that is not a finite number > 0.
    """
    shape, size = _check(shape, size)
    root = ET.fromstring(_arm_xml())
    root.set("model", f"mjx_peg_{shape}_{size * 1000:g}mm")

    compiler = root.find("compiler")
    root.remove(compiler)
    root.insert(0, compiler)
    option = ET.Element(
        "option",
        timestep=_fmt(TIMESTEP),
        integrator="implicitfast",
        cone="pyramidal",
        solver="Newton",
        iterations="20",
        ls_iterations="10",
        gravity="0 0 -9.81",
    )
    root.insert(1, option)
    visual = ET.Element("visual")
    _sub(visual, "global", offwidth=1280, offheight=960, azimuth=150, elevation=-25)
    _sub(
        visual, "headlight", ambient="0.35 0.35 0.35", diffuse="0.5 0.5 0.5", specular="0.1 0.1 0.1"
    )
    _sub(visual, "map", znear=0.01)
    root.insert(2, visual)
    asset = ET.Element("asset")
    grid = dict(rgb1="0.82 0.80 0.76", rgb2="0.74 0.72 0.68", mark="edge", markrgb="0.6 0.58 0.55")
    _sub(asset, "texture", name="grid", type="2d", builtin="checker", width=256, height=256, **grid)
    _sub(asset, "material", name="table", texture="grid", texrepeat="8 8", reflectance="0.05")
    _sub(asset, "material", name="board", rgba="0.36 0.45 0.55 1", specular="0.2")
    _sub(asset, "material", name="peg", rgba="0.95 0.55 0.15 1", specular="0.4")
    root.insert(3, asset)

    worldbody = root.find("worldbody")
    _sub(worldbody, "light", name="top", pos="0.3 0 2.0", dir="0 0 -1", directional="true",
         diffuse="0.6 0.6 0.6", castshadow="false")  # fmt: skip
    table = ET.Element(
        "geom",
        name="table",
        type="plane",
        size="1.5 1.5 0.05",
        material="table",
        contype="2",
        conaffinity="1",
        condim="3",
        group="0",
        friction=_vec(TABLE_FRICTION, 0.005, 0.0001),
    )
    worldbody.insert(0, table)
    _sub(worldbody, "camera", name="birdseye", pos="0.35 0 1.3", xyaxes="0 -1 0 1 0 0", fovy=45)
    eye = (1.25, -0.95, 0.85)
    _sub(
        worldbody,
        "camera",
        name="overview",
        pos=_vec(*eye),
        xyaxes=_look_at_xyaxes(eye, (0.3, 0.05, 0.18)),
        fovy=45,
    )
    _add_board(worldbody, shape, size)
    wrist3 = worldbody.find(f".//body[@name='{WRIST3_BODY}']")
    _add_peg(wrist3, asset, shape, size)

    sensor = ET.SubElement(root, "sensor")
    _sub(sensor, "force", name="ft_force", site="ft")
    _sub(sensor, "torque", name="ft_torque", site="ft")
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


@functools.lru_cache(maxsize=64)  # a few dozen (shape, size) pairs at most
def _compiled(shape: str, size: float) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(build_mjcf(shape, size))


def load_model(shape: str, size: float) -> mujoco.MjModel:
    """The compiled scene for (shape, size in m).

    Compilation is cached per (shape, size) (functools.lru_cache); every call returns an
    independent copy, so callers may overwrite board pose, grasp and friction freely.
    """
    shape, size = _check(shape, size)
    return copy.deepcopy(_compiled(shape, size))


# --- Per-trial model edits (C MuJoCo models; the MJX engine writes the same fields) -------------


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
    ids = scene_ids(model)
    site_id = _id(model, mujoco.mjtObj.mjOBJ_SITE, site)
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
    set_board_pose(model, board_xy[0], board_xy[1], board_yaw)
    target = (board_xy[0], board_xy[1], HOLE_DEPTH + tip_above)
    q = solve_site_pose(model, target, tool_down_rotation(board_yaw))
    data = mujoco.MjData(model)
    data.qpos[scene_ids(model).qpos_adr] = q
    mujoco.mj_forward(model, data)
    return data
