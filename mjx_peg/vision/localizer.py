"""Image + camera calibration -> HoleEstimate in the robot's base frame. NumPy only.

    loc = Localizer.load("runs/vision/model")           # model.npz + model.json
    result = loc.localize(image, CameraCalibration.load("camera.json"))
    result.estimate                                      # robot.runtime.HoleEstimate

Two stages (forward.py): the detector finds the board's hole in the 6 mm/px workspace view
(the most likely 48 mm cell plus its offset, averaged over the view and its mirror image, among
the cells of the task's workspace); the regressor then reads the hole's centre, yaw, shape and
size from a 1.25 mm/px view centred there, and once more from a view re-centred on its own
answer (`refine` passes in all). The mirror averaging and the workspace prior halved the
detector's misses on the held-out renders (15 -> 9 of 1,700 over the val, test and dark splits).

Yaw comes back as the representative nearest the task's board yaw range centre (45 deg):
square in [0, 90) deg, triangle in [-15, 105) deg; a circle's yaw means nothing and is 45 deg.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import numpy as np

from mjx_peg import inputs
from mjx_peg.errors import UsageError
from mjx_peg.outdir import write_json, write_npz
from mjx_peg.robot.runtime import HoleEstimate
from mjx_peg.vision import forward
from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.vision.forward import SHAPE_CLASSES, SIZES_MM
from mjx_peg.vision.views import ViewConfig, coarse_view, fine_view, standardize
from mjx_peg.world.constants import SHAPES, SYMMETRY

SCHEMA = "mjx-peg-vision-localizer"
SCHEMA_VERSION = 1
MODEL_NPZ, MODEL_JSON = "model.npz", "model.json"
YAW_CENTRE = math.pi / 4  # the centre of TaskConfig.board_yaw_range
WORKSPACE_MARGIN = 0.06  # m: a detector cell's half-diagonal (34 mm) and 26 mm more


def default_workspace() -> dict:
    """The task's board workspace (TaskConfig's defaults) and the detector's margin around it."""
    from mjx_peg.world.task import TaskConfig

    task = TaskConfig()
    return {
        "radius_m": list(task.workspace_radius),
        "angle_rad": list(task.workspace_angle),
        "margin_m": WORKSPACE_MARGIN,
    }


class ModelError(UsageError):
    """A model directory that cannot be loaded (one line says why)."""


def _check_workspace(ws) -> None:
    """ValueError unless `ws` is None or a workspace of `default_workspace`'s form."""
    if ws is None:
        return
    if not isinstance(ws, dict):
        raise ValueError("workspace is not an object")
    for name in ("radius_m", "angle_rad"):
        pair = ws.get(name)
        if not (isinstance(pair, list) and len(pair) == 2 and all(_finite(v) for v in pair)):
            raise ValueError(f"workspace.{name} is not two numbers")
    if not _finite(ws.get("margin_m")):
        raise ValueError("workspace.margin_m is not a number")


def _finite(value) -> bool:
    return type(value) in (int, float) and math.isfinite(value)


def yaw_from_encoding(shape_id: int, cos_sin4, cos_sin3) -> float:
    """Yaw (rad) of a shape (a shape class, SHAPE_CLASSES) from its symmetry encoding, as the
    representative nearest 45 deg."""
    n = SYMMETRY[SHAPES.index(SHAPE_CLASSES[shape_id])]
    if n == 0:
        return YAW_CENTRE
    c, s = cos_sin4 if n == 4 else cos_sin3
    period = 2 * math.pi / n
    yaw = math.atan2(s, c) / n
    return float(YAW_CENTRE + np.mod(yaw - YAW_CENTRE + period / 2, period) - period / 2)


@dataclasses.dataclass(frozen=True)
class Localization:
    """A localizer's answer: the estimate and what it was made of."""

    estimate: HoleEstimate
    coarse_xy: tuple[float, float]  # the detector's hole centre (m)
    detector_score: float  # the detector's softmax probability of its cell
    shape_probs: tuple[float, ...]  # circle, square, triangle
    size_probs: tuple[float, ...]  # 25, 50, 60 mm

    def to_json(self) -> dict:
        e = self.estimate
        return {
            "x": e.x,
            "y": e.y,
            "yaw": e.yaw,
            "yaw_deg": math.degrees(e.yaw),
            "shape": e.shape,
            "size": e.size,
            "hole_scale": e.hole_scale,
            "frame": "robot base",
            "coarse_xy": list(self.coarse_xy),
            "detector_score": self.detector_score,
            "shape_probs": list(self.shape_probs),
            "size_probs": list(self.size_probs),
        }


class Localizer:
    """The exported localizer: architecture + view config (JSON) and weights (npz)."""

    def __init__(self, config: dict, params: dict[str, np.ndarray]):
        self.config = config
        self.arch = config["arch"]
        self.views = ViewConfig.from_json(config["views"])
        self.params = {k: np.asarray(v, dtype=np.float32) for k, v in params.items()}
        self._mask = None

    @classmethod
    def load(cls, model_dir: str | os.PathLike) -> Localizer:
        """Read model.json + model.npz (allow_pickle=False); ModelError if unusable."""
        model_dir = Path(model_dir)
        jpath, npath = model_dir / MODEL_JSON, model_dir / MODEL_NPZ
        if not (jpath.exists() and npath.exists()):
            raise ModelError(f"{model_dir} holds no {MODEL_JSON} + {MODEL_NPZ}: train one first")
        what = "a localizer's model.json"
        config = inputs.read_json(jpath, what, error=ModelError, allow_nan=True)
        if not isinstance(config, dict) or config.get("schema") != SCHEMA:
            raise ModelError(f"{jpath} is not an mjx-peg localizer")
        if config.get("schema_version") != SCHEMA_VERSION:
            raise ModelError(f"{jpath} is not a version-{SCHEMA_VERSION} mjx-peg localizer")
        try:
            views = ViewConfig.from_json(config["views"])
            shapes = forward.param_shapes(config["arch"], views.fine_size)
            _check_workspace(config.get("workspace"))
            refine = config.get("refine", 2)
            if type(refine) is not int or not 0 <= refine <= 10:
                raise ValueError("refine is not a count in 0..10")
        except (KeyError, TypeError, ValueError) as e:
            why = f"it lacks {e}" if isinstance(e, KeyError) else " ".join(str(e).split())[:120]
            raise ModelError(f"{jpath}: {why}") from None
        members = {name: inputs.Member("f", shape) for name, shape in shapes.items()}
        return cls(config, inputs.read_npz(npath, members, error=ModelError))

    def save(self, model_dir: str | os.PathLike) -> Path:
        """Write model.npz + model.json into model_dir, each atomically."""
        model_dir = Path(model_dir)
        model_dir.mkdir(parents=True, exist_ok=True)
        write_npz(model_dir / MODEL_NPZ, self.params)
        write_json(model_dir / MODEL_JSON, self.config)
        return model_dir

    @property
    def shapes(self) -> tuple[str, ...]:
        """The shapes it localizes: its shape classes (model.json "classes"), the only ones it
        can name and whose yaw it encodes."""
        return tuple(self.config.get("classes", {}).get("shapes", SHAPE_CLASSES))

    def check_shape(self, shape: str, flag: str = "--shape") -> str:
        """`shape` if the localizer localizes it, else UsageError (one line) saying it cannot."""
        if shape not in SHAPES:
            raise UsageError(f"{flag}: unknown shape {shape!r}: choose from {', '.join(SHAPES)}")
        if shape not in self.shapes:
            raise UsageError(
                f"{flag} {shape}: this localizer cannot localize {shape} holes (it names and "
                f"finds the yaw of {', '.join(self.shapes)} only); measure the hole yourself"
            )
        return shape

    # --- the two stages -----------------------------------------------------------------------

    def workspace_mask(self) -> np.ndarray:
        """(h, w) bool: detector cells whose centre lies within `margin` of the workspace sector
        (the task's annular sector of board positions; the margin covers a cell's half-diagonal).
        Boards are never placed elsewhere, so the detector may not answer elsewhere."""
        if self._mask is None:
            ws = self.config.get("workspace") or default_workspace()
            h, w = self.views.coarse_cells
            rc = np.stack(np.meshgrid(np.arange(h), np.arange(w), indexing="ij"), -1) + 0.5
            xy = self.views.coarse_to_world(rc * self.views.coarse_stride)
            r = np.hypot(xy[..., 0], xy[..., 1])
            angle = np.arctan2(xy[..., 1], xy[..., 0])
            m = ws["margin_m"]
            (r0, r1), (a0, a1) = ws["radius_m"], ws["angle_rad"]
            beyond = np.maximum(a0 - angle, angle - a1) * np.maximum(r, 1e-9)  # arc length
            self._mask = (r >= r0 - m) & (r <= r1 + m) & (beyond <= m)
        return self._mask

    def detect(self, image: np.ndarray, calib: CameraCalibration) -> tuple[np.ndarray, float]:
        """((2,) world x, y of the hole by the detector, its cell probability).

        The detector runs on the workspace view and on its left-right mirror image (test-time
        augmentation: the same view, flipped back); the cell probabilities and offsets of both
        are averaged, and cells outside the workspace are ruled out.
        """
        view = standardize(coarse_view(image, calib, self.views))
        both = np.stack([view, view[:, ::-1]])
        out = forward.detector_forward(self.arch["detector"], self.params, both)
        mirrored = out[1, :, ::-1].copy()
        mirrored[..., 2] = -mirrored[
            ..., 2
        ]  # column offset o -> 1 - o: sigmoid(-x) = 1 - sigmoid(x)
        mask = self.workspace_mask().ravel()
        probs = 0.0
        for o in (out[0], mirrored):
            logits = np.where(mask, o[..., 0].ravel(), -np.inf)
            probs = probs + 0.5 * forward.softmax(logits)
        probs = probs.reshape(out.shape[1:3])
        r, c = np.unravel_index(int(np.argmax(probs)), probs.shape)
        off = 0.5 * (forward.sigmoid(out[0, r, c, 1:]) + forward.sigmoid(mirrored[r, c, 1:]))
        rc = (np.array([r, c]) + off) * self.views.coarse_stride
        return self.views.coarse_to_world(rc), float(probs[r, c])

    def regress(self, image: np.ndarray, calib: CameraCalibration, centre_xy) -> np.ndarray:
        """(12,) regressor outputs for the view centred on `centre_xy`."""
        view = standardize(fine_view(image, calib, centre_xy, self.views))[None]
        return forward.regressor_forward(self.arch["regressor"], self.params, view)[0]

    def localize(
        self,
        image: np.ndarray,
        calib: CameraCalibration,
        refine: int | None = None,
        shape: str | None = None,
    ) -> Localization:
        """The hole in `image` (H, W, 3) uint8 taken by the camera `calib`; `shape`: the part's,
        when known (its yaw is then read at that shape's symmetry; UsageError if the localizer
        cannot localize it), else the shape it classifies."""
        if shape is not None:
            self.check_shape(shape)
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] != 3:
            raise UsageError(f"the image must be H x W x 3 (RGB), got shape {image.shape}")
        refine = int(self.config.get("refine", 2) if refine is None else refine)
        coarse, score = self.detect(image, calib)
        centre = coarse
        for _ in range(max(refine, 1)):
            out = self.regress(image, calib, centre)
            centre = centre + forward.OFFSET_SCALE * out[:2]
        shape_probs = forward.softmax(out[6:9])
        size_probs = forward.softmax(out[9:12])
        shape_id = int(np.argmax(shape_probs)) if shape is None else SHAPE_CLASSES.index(shape)
        yaw = yaw_from_encoding(shape_id, out[2:4], out[4:6])
        estimate = HoleEstimate(
            float(centre[0]),
            float(centre[1]),
            yaw,
            SHAPE_CLASSES[shape_id],
            SIZES_MM[int(np.argmax(size_probs))] / 1000.0,
        )
        return Localization(
            estimate,
            (float(coarse[0]), float(coarse[1])),
            score,
            tuple(float(p) for p in shape_probs),
            tuple(float(p) for p in size_probs),
        )
