"""Domain randomization for the bird's-eye camera: what a real camera and workshop would vary.

The scene is the task's own (`mjcf.build_mjcf`: UR5e, table, board with its box-built hole, peg)
with extras that only the camera sees: table and board materials with textures, a second
(shadow-casting) light, and distractor bodies (no contacts). Per image, `sample_view` draws a
view (a plain dict, stored in the image's JSON label) and `apply_view` writes it into the model.
The training range (condition `nominal`):

- board: hole centre uniform in area over the task's workspace sector, yaw uniform in
  [0, 360) deg, shape circle / square / triangle, size 25 / 50 / 60 mm (the localizer's classes;
  a split may render any of constants.SHAPES at any size in constants.SIZE_RANGE, at the shape's
  paper fit);
- table: 4 textures (checker, speckle, gradient, plain) x colour (HSV) x scale (texrepeat
  2-14), glossy (reflectance up to 0.05) 30 % of the time;
- board look: 3 textures (plain, speckle, gradient) x colour (HSV) x specular / shininess;
- lights: headlight ambient 0.15-0.45, diffuse 0.2-0.55; the top light diffuse 0.2-0.6,
  tilted 0-30 deg; a key light diffuse 0.15-0.5, 20-55 deg from vertical, casting shadows
  half the time; a common tint 0.9-1.0 per channel;
- camera mount: +-20 mm per axis and +-1 deg about each axis around the scene's `birdseye`
  camera (the calibration follows the mount: a mounted camera is calibrated where it is);
- calibration error: the true camera is off its calibration by +-1 mm per axis and
  +-0.05 deg about each axis (uniform; ~1 mm on the board at 1.2 m);
- distractors: 0-8 of boxes, cylinders, spheres, capsules (half-sizes 8-60 mm) and
  board-sized hole-less slabs, anywhere on the table off the board;
- arm: parked behind its base (x < 0.1 m), joints jittered;
- sensor (`postprocess`): exposure x0.75-1.25, white balance x0.92-1.08 per channel, gamma
  0.85-1.15, Gaussian blur sigma 0-1.2 px, read noise sigma 0.5-4 DN plus shot noise (up to
  0.6 DN at mid grey), 8-bit quantization.

Out-of-range conditions for the robustness check: `dark` (every light x0.3, beyond the training
minimum) and `camera-off` (the true camera 10 mm and 1 deg off its calibration, in random
directions, 10x / 20x the training calibration error).
"""

from __future__ import annotations

import colorsys
import copy
import functools
import math
import xml.etree.ElementTree as ET

from mjx_peg.errors import UsageError
from mjx_peg.world import gl

gl.choose_backend()  # before MuJoCo is first imported

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from mjx_peg.vision.camera import CameraCalibration  # noqa: E402
from mjx_peg.vision.forward import SHAPE_CLASSES, SIZES_MM  # noqa: E402
from mjx_peg.world import constants, mjcf, scene  # noqa: E402
from mjx_peg.world.task import TaskConfig  # noqa: E402

CONDITIONS = ("nominal", "dark", "camera-off")
CAMERA = "birdseye"
TABLE_TEXTURES = ("checker", "speckle", "gradient", "plain")
BOARD_TEXTURES = ("plain", "speckle", "gradient")
N_DISTRACTORS = {"box": 3, "cylinder": 2, "sphere": 2, "capsule": 2, "slab": 2}
PARK_Z = -2.0  # m: unused distractors wait under the table (the table hides them)

CAMERA_MOUNT_M = 0.02  # +- per axis, known (the calibration follows it)
CAMERA_MOUNT_DEG = 1.0
CALIB_ERROR_M = 0.001  # +- per axis, the true camera's offset from its calibration
CALIB_ERROR_DEG = 0.05
CAMERA_OFF_M, CAMERA_OFF_DEG = 0.010, 1.0  # the out-of-range `camera-off` condition
DARK_FACTOR = 0.3  # the `dark` condition's light scale


def build_vision_mjcf(shape: str, size: float) -> str:
    """The task scene (`mjcf.build_mjcf`) plus camera-only extras: materials, a key light and
    distractor bodies (contype = conaffinity = 0, parked under the table)."""
    root = ET.fromstring(mjcf.build_mjcf(shape, size))
    asset = root.find("asset")
    tex = dict(type="2d", width=512, height=512)
    mjcf.element(
        asset,
        "texture",
        name="vt_checker",
        builtin="checker",
        rgb1="1 1 1",
        rgb2="0.72 0.72 0.72",
        mark="edge",
        markrgb="0.5 0.5 0.5",
        **tex,
    )
    mjcf.element(
        asset,
        "texture",
        name="vt_speckle",
        builtin="flat",
        rgb1="0.92 0.92 0.92",
        mark="random",
        random="0.08",
        markrgb="0.55 0.55 0.55",
        **tex,
    )
    mjcf.element(
        asset,
        "texture",
        name="vt_gradient",
        builtin="gradient",
        rgb1="1 1 1",
        rgb2="0.55 0.55 0.55",
        **tex,
    )
    for name in TABLE_TEXTURES:
        extra = {} if name == "plain" else {"texture": f"vt_{name}"}
        mjcf.element(asset, "material", name=f"vm_table_{name}", texrepeat="8 8", **extra)
    for name in BOARD_TEXTURES:
        extra = {} if name == "plain" else {"texture": f"vt_{name}", "texuniform": "true"}
        mjcf.element(asset, "material", name=f"vm_board_{name}", texrepeat="6 6", **extra)
    world = root.find("worldbody")
    mjcf.element(
        world,
        "light",
        name="key",
        pos="0.4 0.3 2.0",
        dir="0 0 -1",
        directional="true",
        diffuse="0.3 0.3 0.3",
        specular="0.1 0.1 0.1",
        castshadow="true",
    )
    for kind, count in N_DISTRACTORS.items():
        for k in range(count):
            body = mjcf.element(world, "body", name=f"vd_{kind}{k}", pos=f"0 0 {PARK_Z}")
            gtype = "box" if kind == "slab" else kind
            mjcf.element(
                body,
                "geom",
                name=f"vd_{kind}{k}",
                type=gtype,
                size="0.02 0.02 0.02",
                contype=0,
                conaffinity=0,
                group=0,
                rgba="0.5 0.5 0.5 1",
            )
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


@functools.lru_cache(maxsize=16)
def _compiled(shape: str, size: float) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(build_vision_mjcf(shape, size))


def load_vision_model(shape: str, size: float) -> mujoco.MjModel:
    """An independent copy of the compiled vision scene for (shape, size in m)."""
    return copy.deepcopy(_compiled(shape, float(size)))


def _rgb(rng: np.random.Generator, sat=(0.0, 0.8), val=(0.25, 0.95)) -> list[float]:
    h, s, v = rng.uniform(0, 1), rng.uniform(*sat), rng.uniform(*val)
    return [round(c, 4) for c in colorsys.hsv_to_rgb(h, s, v)]


def _rotation(rotvec) -> np.ndarray:
    """(3, 3) rotation matrix of a rotation vector (rad)."""
    rotvec = np.asarray(rotvec, dtype=np.float64)
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-15:
        return np.eye(3)
    k = rotvec / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx


def _unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def nominal_camera(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, float]:
    """(position (3,), MuJoCo frame (3, 3), fovy deg) of the scene's bird's-eye camera."""
    cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA)
    quat = np.array(model.cam_quat[cam])
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, quat)
    return np.array(model.cam_pos[cam]), mat.reshape(3, 3), float(model.cam_fovy[cam])


def sample_board(
    rng: np.random.Generator,
    shapes: tuple[str, ...] = SHAPE_CLASSES,
    sizes_mm: tuple[float, ...] = SIZES_MM,
    task: TaskConfig | None = None,
) -> dict:
    """A board: shape and size (m) uniform over the given ones, hole centre uniform in area over
    the task's workspace sector, yaw uniform in [0, 2 pi)."""
    task = task or TaskConfig()
    r0, r1 = task.workspace_radius
    radius = math.sqrt(rng.uniform(r0**2, r1**2))
    angle = rng.uniform(*task.workspace_angle)
    return {
        "shape": shapes[int(rng.integers(len(shapes)))],
        "size": sizes_mm[int(rng.integers(len(sizes_mm)))] / 1000.0,
        "x": radius * math.cos(angle),
        "y": radius * math.sin(angle),
        "yaw": rng.uniform(0.0, 2.0 * math.pi),
    }


def sample_view(
    rng: np.random.Generator,
    board: dict,
    condition: str = "nominal",
    width: int = 1280,
    height: int = 960,
) -> dict:
    """Everything random about one image of `board` (JSON-able; `apply_view` writes it)."""
    if condition not in CONDITIONS:
        raise UsageError(f"unknown condition {condition!r}: choose from {', '.join(CONDITIONS)}")
    model = _compiled(board["shape"], float(board["size"]))
    pos0, mat0, fovy = nominal_camera(model)
    mount_pos = pos0 + rng.uniform(-CAMERA_MOUNT_M, CAMERA_MOUNT_M, 3)
    mount_mat = _rotation(np.radians(rng.uniform(-CAMERA_MOUNT_DEG, CAMERA_MOUNT_DEG, 3))) @ mat0
    if condition == "camera-off":
        off_pos = CAMERA_OFF_M * _unit(rng)
        off_rot = math.radians(CAMERA_OFF_DEG) * _unit(rng)
    else:
        off_pos = rng.uniform(-CALIB_ERROR_M, CALIB_ERROR_M, 3)
        off_rot = np.radians(rng.uniform(-CALIB_ERROR_DEG, CALIB_ERROR_DEG, 3))
    true_pos = mount_pos + off_pos
    true_mat = _rotation(off_rot) @ mount_mat
    calib = CameraCalibration.from_mujoco(mount_pos, mount_mat, fovy, width, height)
    true_calib = CameraCalibration.from_mujoco(true_pos, true_mat, fovy, width, height)

    light = DARK_FACTOR if condition == "dark" else 1.0
    tilt, azim = math.radians(rng.uniform(0, 30)), rng.uniform(0, 2 * math.pi)
    key_tilt, key_azim = math.radians(rng.uniform(20, 55)), rng.uniform(0, 2 * math.pi)

    def direction(t, a):
        return [-math.sin(t) * math.cos(a), -math.sin(t) * math.sin(a), -math.cos(t)]

    lights = {
        "head_ambient": light * rng.uniform(0.15, 0.45),
        "head_diffuse": light * rng.uniform(0.2, 0.55),
        "top_diffuse": light * rng.uniform(0.2, 0.6),
        "top_dir": direction(tilt, azim),
        "key_diffuse": light * rng.uniform(0.15, 0.5),
        "key_dir": direction(key_tilt, key_azim),
        "key_shadow": bool(rng.uniform() < 0.5),
        "tint": [round(float(v), 4) for v in rng.uniform(0.9, 1.0, 3)],
    }
    table = {
        "texture": TABLE_TEXTURES[int(rng.integers(len(TABLE_TEXTURES)))],
        "rgb": _rgb(rng, sat=(0.0, 0.5), val=(0.35, 1.0)),
        "repeat": float(rng.uniform(2, 14)),
        "reflectance": float(rng.uniform(0, 0.05)) if rng.uniform() < 0.3 else 0.0,
    }
    board_look = {
        "texture": BOARD_TEXTURES[int(rng.integers(len(BOARD_TEXTURES)))],
        "rgb": _rgb(rng, sat=(0.0, 0.9), val=(0.15, 0.95)),
        "specular": float(rng.uniform(0.0, 0.5)),
        "shininess": float(rng.uniform(0.1, 0.9)),
        "repeat": float(rng.uniform(2, 10)),
    }
    distractors = []
    kinds = [(kind, k) for kind, n in N_DISTRACTORS.items() for k in range(n)]
    count = int(rng.integers(0, 9))
    keep_out = mjcf.board_half_width(board["shape"], board["size"]) * math.sqrt(2.0) + 0.01
    for i in rng.permutation(len(kinds))[:count]:
        kind, k = kinds[i]
        if kind == "slab":
            half = rng.uniform(0.08, 0.12)
            size = [half, half * rng.uniform(0.8, 1.2), constants.HOLE_DEPTH / 2]
        elif kind == "box":
            size = list(rng.uniform(0.008, 0.06, 3))
        elif kind == "sphere":
            size = [rng.uniform(0.01, 0.05), 0.0, 0.0]
        else:
            size = [rng.uniform(0.008, 0.04), rng.uniform(0.01, 0.06), 0.0]
        reach = float(np.linalg.norm(size)) + keep_out
        for _ in range(50):  # off the board; may leave the view
            x, y = rng.uniform(-0.1, 0.9), rng.uniform(-0.75, 0.75)
            if math.hypot(x - board["x"], y - board["y"]) > reach and x > 0.1:
                break
        else:
            continue
        z = size[2] if kind in ("box", "slab") else size[0]
        if kind in ("cylinder", "capsule"):
            z = size[1] + (size[0] if kind == "capsule" else 0.0)
        distractors.append(
            {
                "name": f"vd_{kind}{k}",
                "size": [float(s) for s in size],
                "pos": [float(x), float(y), float(z)],
                "yaw": float(rng.uniform(0, 2 * math.pi)),
                "rgb": _rgb(rng, sat=(0.0, 1.0), val=(0.1, 1.0)),
            }
        )
    arm_q = [
        rng.uniform(-0.6, 0.6),
        rng.uniform(-2.2, -1.2),
        rng.uniform(1.0, 2.4),
        rng.uniform(-2.2, -0.8),
        rng.uniform(-1.8, -1.3),
        rng.uniform(-math.pi, math.pi),
    ]
    sensor = {
        "gain": float(rng.uniform(0.75, 1.25)),
        "white_balance": [float(v) for v in rng.uniform(0.92, 1.08, 3)],
        "gamma": float(rng.uniform(0.85, 1.15)),
        "blur_px": float(rng.uniform(0.0, 1.2)),
        "read_noise": float(rng.uniform(0.5, 4.0)),
        "shot_noise": float(rng.uniform(0.0, 0.6)),
        "seed": int(rng.integers(2**31)),
    }
    return {
        "condition": condition,
        "camera_true": true_calib.to_json(),
        "calibration": calib.to_json(),
        "fovy_deg": fovy,
        "lights": lights,
        "table": table,
        "board_look": board_look,
        "distractors": distractors,
        "arm_q": [float(q) for q in arm_q],
        "sensor": sensor,
    }


def _mat_id(model, name: str) -> int:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_MATERIAL, name)


def apply_view(model: mujoco.MjModel, data: mujoco.MjData, board: dict, view: dict) -> None:
    """Write a board pose and a `sample_view` draw into the vision model, then mj_forward."""
    obj = mujoco.mjtObj
    scene.set_board_pose(model, board["x"], board["y"], board["yaw"])
    # Camera: the true pose (OpenCV axes back to MuJoCo's).
    true = CameraCalibration.from_json(view["camera_true"])
    cam = mujoco.mj_name2id(model, obj.mjOBJ_CAMERA, CAMERA)
    mat = true.R_base_camera @ np.diag([1.0, -1.0, -1.0])
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, mat.ravel())
    model.cam_pos[cam] = true.t_base_camera
    model.cam_quat[cam] = quat
    # Lights.
    lt = view["lights"]
    tint = np.asarray(lt["tint"])
    model.vis.headlight.ambient[:] = lt["head_ambient"] * tint
    model.vis.headlight.diffuse[:] = lt["head_diffuse"] * tint
    top = mujoco.mj_name2id(model, obj.mjOBJ_LIGHT, "top")
    key = mujoco.mj_name2id(model, obj.mjOBJ_LIGHT, "key")
    model.light_diffuse[top] = lt["top_diffuse"] * tint
    model.light_dir[top] = lt["top_dir"]
    model.light_diffuse[key] = lt["key_diffuse"] * tint
    model.light_specular[key] = 0.3 * lt["key_diffuse"] * tint
    model.light_dir[key] = lt["key_dir"]
    model.light_castshadow[key] = lt["key_shadow"]
    # Table and board materials.
    table_geom = mujoco.mj_name2id(model, obj.mjOBJ_GEOM, "table")
    t = view["table"]
    m = _mat_id(model, f"vm_table_{t['texture']}")
    model.geom_matid[table_geom] = m
    model.mat_rgba[m] = (*t["rgb"], 1.0)
    model.mat_texrepeat[m] = (t["repeat"], t["repeat"])
    model.mat_reflectance[m] = t["reflectance"]
    model.mat_specular[m] = 0.1
    b = view["board_look"]
    m = _mat_id(model, f"vm_board_{b['texture']}")
    model.geom_matid[scene.board_geom_ids(model)] = m
    model.mat_rgba[m] = (*b["rgb"], 1.0)
    model.mat_specular[m] = b["specular"]
    model.mat_shininess[m] = b["shininess"]
    model.mat_texrepeat[m] = (b["repeat"], b["repeat"])
    # Distractors: park all, then place the drawn ones.
    for kind, count in N_DISTRACTORS.items():
        for k in range(count):
            body = mujoco.mj_name2id(model, obj.mjOBJ_BODY, f"vd_{kind}{k}")
            model.body_pos[body] = (0.0, 0.0, PARK_Z)
    for d in view["distractors"]:
        body = mujoco.mj_name2id(model, obj.mjOBJ_BODY, d["name"])
        geom = mujoco.mj_name2id(model, obj.mjOBJ_GEOM, d["name"])
        model.body_pos[body] = d["pos"]
        model.body_quat[body] = (math.cos(d["yaw"] / 2), 0.0, 0.0, math.sin(d["yaw"] / 2))
        model.geom_size[geom] = d["size"]
        model.geom_rgba[geom] = (*d["rgb"], 1.0)
        model.geom_rbound[geom] = float(np.linalg.norm(d["size"])) + 0.05
    # The arm, parked.
    ids = scene.scene_ids(model)
    mujoco.mj_resetData(model, data)
    data.qpos[ids.qpos_adr] = view["arm_q"]
    mujoco.mj_forward(model, data)


def postprocess(rgb: np.ndarray, sensor: dict) -> np.ndarray:
    """(H, W, 3) uint8: the rendered frame through a camera's sensor (exposure, white balance,
    gamma, optics blur, shot and read noise, 8-bit quantization), seeded by sensor['seed']."""
    from scipy.ndimage import gaussian_filter

    img = rgb.astype(np.float32) / 255.0
    img = img * (sensor["gain"] * np.asarray(sensor["white_balance"], dtype=np.float32))
    img = np.clip(img, 0.0, 1.0) ** np.float32(sensor["gamma"])
    if sensor["blur_px"] > 0.05:
        img = gaussian_filter(img, sigma=(sensor["blur_px"], sensor["blur_px"], 0.0))
    img *= 255.0
    rng = np.random.default_rng(sensor["seed"])
    sigma = np.sqrt(sensor["read_noise"] ** 2 + sensor["shot_noise"] ** 2 * img / 127.5)
    img += sigma * rng.standard_normal(img.shape, dtype=np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)
