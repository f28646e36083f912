"""A calibrated pinhole camera: projection, its JSON file, and rectification onto a table plane.

NumPy only. Conventions (OpenCV's, what a real camera's calibration tools write):

- Camera frame: x right, y down, z forward (along the optical axis).
- Pixels: u right (column), v down (row); pixel (u, v) = (0, 0) is the *centre* of the top-left
  pixel, so a symmetric frustum has cx = (width - 1) / 2.
- Intrinsics fx, fy, cx, cy (px); optional distortion (k1, k2, p1, p2, k3), OpenCV's
  radial-tangential model, applied in projection (rectification only ever projects).
- Extrinsics: the camera's pose in the robot's base frame (= world frame, CONVENTIONS.md):
  `R_base_camera` (3x3, columns = the camera axes in base coordinates) and `t_base_camera` (m).

The calibration file (JSON; every length in m, angles never appear):

    {"width": 1280, "height": 960,
     "intrinsics": {"fx": 1158.8, "fy": 1158.8, "cx": 639.5, "cy": 479.5},
     "distortion": [0, 0, 0, 0, 0],                      (optional)
     "extrinsics": {"R_base_camera": [[...], [...], [...]], "t_base_camera": [x, y, z]}}

A MuJoCo camera (frame: x right, y up, looking along -z; vertical field of view fovy) is the
pinhole with fx = fy = (height / 2) / tan(fovy / 2), cx = (width - 1) / 2, cy = (height - 1) / 2
and R_base_camera = R_mujoco diag(1, -1, -1) (`from_mujoco`; tests/vision/test_vision.py checks a
rendered marker against it to a pixel).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np

from mjx_peg import inputs
from mjx_peg.errors import UsageError

MAX_PIXELS = 16_384  # a camera image's width or height


class CalibrationError(UsageError):
    """A calibration file or dict that cannot be used (one line says why)."""


@dataclasses.dataclass(frozen=True)
class CameraCalibration:
    """Intrinsics (px), distortion and the camera pose in the base frame (OpenCV axes)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    R_base_camera: np.ndarray  # (3, 3) rotation, columns = camera x, y, z in the base frame
    t_base_camera: np.ndarray  # (3,) camera centre in the base frame (m)
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)  # k1, k2, p1, p2, k3

    def __post_init__(self):
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise CalibrationError(f"calibration {name} must be a positive integer (px)")
            if not 1 <= value <= MAX_PIXELS:
                raise CalibrationError(f"calibration {name} must be in 1..{MAX_PIXELS:,} px")
        for name in ("fx", "fy", "cx", "cy"):
            value = getattr(self, name)
            if not isinstance(value, int | float | np.floating) or not math.isfinite(value):
                raise CalibrationError(f"calibration intrinsics.{name} must be a finite number")
            object.__setattr__(self, name, float(value))
        if self.fx <= 0 or self.fy <= 0:
            raise CalibrationError("calibration focal lengths fx, fy must be positive (px)")
        rot = np.asarray(self.R_base_camera, dtype=np.float64)
        pos = np.asarray(self.t_base_camera, dtype=np.float64)
        if rot.shape != (3, 3) or not np.all(np.isfinite(rot)):
            raise CalibrationError("calibration extrinsics.R_base_camera must be a finite 3x3")
        if np.abs(rot @ rot.T - np.eye(3)).max() > 1e-6 or np.linalg.det(rot) < 0:
            raise CalibrationError("calibration extrinsics.R_base_camera is not a rotation")
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise CalibrationError("calibration extrinsics.t_base_camera must be 3 finite numbers")
        dist = tuple(float(v) for v in self.distortion)
        if len(dist) != 5 or not all(math.isfinite(v) for v in dist):
            raise CalibrationError("calibration distortion must be 5 numbers (k1, k2, p1, p2, k3)")
        rot.setflags(write=False)
        pos.setflags(write=False)
        object.__setattr__(self, "R_base_camera", rot)
        object.__setattr__(self, "t_base_camera", pos)
        object.__setattr__(self, "distortion", dist)

    # --- construction -------------------------------------------------------------------------

    @classmethod
    def from_mujoco(
        cls, cam_pos, cam_mat, fovy_deg: float, width: int, height: int
    ) -> CameraCalibration:
        """The exact calibration of a MuJoCo camera: world position (3,), world frame (3, 3)
        (data.cam_xpos, data.cam_xmat reshaped), vertical field of view (deg), image size."""
        f = 0.5 * height / math.tan(0.5 * math.radians(fovy_deg))
        rot = np.asarray(cam_mat, dtype=np.float64).reshape(3, 3) @ np.diag([1.0, -1.0, -1.0])
        return cls(
            width=int(width),
            height=int(height),
            fx=f,
            fy=f,
            cx=0.5 * (width - 1),
            cy=0.5 * (height - 1),
            R_base_camera=rot,
            t_base_camera=np.asarray(cam_pos, dtype=np.float64),
        )

    def to_json(self) -> dict:
        """The calibration file's content (see the module docstring)."""
        return {
            "width": self.width,
            "height": self.height,
            "intrinsics": {"fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy},
            "distortion": list(self.distortion),
            "extrinsics": {
                "R_base_camera": self.R_base_camera.tolist(),
                "t_base_camera": self.t_base_camera.tolist(),
            },
        }

    @classmethod
    def from_json(cls, doc) -> CameraCalibration:
        """Parse the calibration file's content; CalibrationError (one line) if it is unusable."""
        if not isinstance(doc, dict):
            raise CalibrationError("a camera calibration must be a JSON object")
        for key in ("width", "height", "intrinsics", "extrinsics"):
            if key not in doc:
                raise CalibrationError(f"the camera calibration has no {key!r}")
        intr, extr = doc["intrinsics"], doc["extrinsics"]
        if not isinstance(intr, dict) or not isinstance(extr, dict):
            raise CalibrationError("calibration intrinsics and extrinsics must be JSON objects")
        for key in ("fx", "fy", "cx", "cy"):
            if key not in intr:
                raise CalibrationError(f"the camera calibration's intrinsics have no {key!r}")
        for key in ("R_base_camera", "t_base_camera"):
            if key not in extr:
                raise CalibrationError(f"the camera calibration's extrinsics have no {key!r}")
        try:
            rot = np.asarray(extr["R_base_camera"], dtype=np.float64)
            pos = np.asarray(extr["t_base_camera"], dtype=np.float64)
            dist = tuple(float(v) for v in doc.get("distortion") or (0.0,) * 5)
        except (TypeError, ValueError):
            raise CalibrationError(
                "calibration extrinsics and distortion must be numbers"
            ) from None
        return cls(
            width=doc["width"],
            height=doc["height"],
            fx=intr["fx"],
            fy=intr["fy"],
            cx=intr["cx"],
            cy=intr["cy"],
            R_base_camera=rot,
            t_base_camera=pos,
            distortion=dist,
        )

    @classmethod
    def load(cls, path: str | os.PathLike) -> CameraCalibration:
        """Read a calibration JSON file; CalibrationError (one line) if missing or unusable."""
        path = Path(path)
        if not path.exists():
            raise CalibrationError(f"camera calibration {path} does not exist")
        doc = inputs.read_json(path, "a camera calibration", error=CalibrationError)
        try:
            return cls.from_json(doc)
        except (CalibrationError, KeyError, TypeError, AttributeError) as exc:
            why = f"it lacks {exc}" if isinstance(exc, KeyError) else " ".join(str(exc).split())
            raise CalibrationError(f"{path}: {why[:160]}") from None

    def save(self, path: str | os.PathLike) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_json(), indent=2) + "\n")
        return path

    # --- geometry -----------------------------------------------------------------------------

    def project(self, points_base) -> np.ndarray:
        """(..., 2) pixel coordinates (u, v) of (..., 3) points in the base frame.

        Points behind the camera get NaN.
        """
        p = np.asarray(points_base, dtype=np.float64)
        cam = (p - self.t_base_camera) @ self.R_base_camera  # R^T (p - t), batched
        z = cam[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.where(z > 0, cam[..., 0] / z, np.nan)
            y = np.where(z > 0, cam[..., 1] / z, np.nan)
        k1, k2, p1, p2, k3 = self.distortion
        if any(self.distortion):
            r2 = x * x + y * y
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            x, y = (
                x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
            )
        return np.stack([self.fx * x + self.cx, self.fy * y + self.cy], axis=-1)

    def unproject_to_plane(self, uv, plane_z: float) -> np.ndarray:
        """(..., 3) base-frame points on the plane z = plane_z seen at pixels (..., 2) (u, v).

        Distortion is undone by fixed-point iteration (OpenCV's undistortPoints scheme).
        """
        uv = np.asarray(uv, dtype=np.float64)
        xd = (uv[..., 0] - self.cx) / self.fx
        yd = (uv[..., 1] - self.cy) / self.fy
        x, y = xd, yd
        k1, k2, p1, p2, k3 = self.distortion
        if any(self.distortion):
            for _ in range(20):
                r2 = x * x + y * y
                radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
                dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
                dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
                x, y = (xd - dx) / radial, (yd - dy) / radial
        ray = np.stack([x, y, np.ones_like(x)], axis=-1) @ self.R_base_camera.T
        scale = (plane_z - self.t_base_camera[2]) / ray[..., 2]
        return self.t_base_camera + scale[..., None] * ray

    def metres_per_pixel(self, plane_z: float = 0.0) -> float:
        """Ground sampling distance (m/px) at the image centre on the plane z = plane_z."""
        axis = self.R_base_camera[:, 2]
        depth = (self.t_base_camera[2] - plane_z) / max(-axis[2], 1e-9)
        return depth / math.sqrt(self.fx * self.fy)


def plane_grid(centre_xy, rows: int, cols: int, res_m: float) -> np.ndarray:
    """(rows, cols, 2) world (x, y) of the pixel centres of a top-down view of a table plane.

    The view is laid out like the bird's-eye camera's image: up = world +x, right = world -y;
    `centre_xy` is the view's centre, `res_m` its pixel size (m).
    """
    r = (0.5 * rows - 0.5 - np.arange(rows)) * res_m  # +x up
    c = (0.5 * cols - 0.5 - np.arange(cols)) * res_m  # -y right
    x = centre_xy[0] + r[:, None] + 0.0 * c[None, :]
    y = centre_xy[1] + c[None, :] + 0.0 * r[:, None]
    return np.stack([x, y], axis=-1)


def bilinear(image: np.ndarray, uv: np.ndarray, fill: float = 0.0) -> np.ndarray:
    """(..., C) samples of an (H, W, C) image at (..., 2) pixel coordinates (u, v), bilinear;
    points outside the image (or NaN) get `fill`."""
    img = np.asarray(image, dtype=np.float32)
    h, w = img.shape[:2]
    u, v = uv[..., 0], uv[..., 1]
    inside = (u >= 0) & (u <= w - 1) & (v >= 0) & (v <= h - 1)
    u = np.where(inside, u, 0.0)
    v = np.where(inside, v, 0.0)
    u0 = np.minimum(np.floor(u).astype(np.int64), w - 2)
    v0 = np.minimum(np.floor(v).astype(np.int64), h - 2)
    a = (u - u0)[..., None].astype(np.float32)
    b = (v - v0)[..., None].astype(np.float32)
    top = img[v0, u0] * (1 - a) + img[v0, u0 + 1] * a
    bottom = img[v0 + 1, u0] * (1 - a) + img[v0 + 1, u0 + 1] * a
    out = top * (1 - b) + bottom * b
    return np.where(inside[..., None], out, np.float32(fill))


def rectify(
    image: np.ndarray,
    calib: CameraCalibration,
    centre_xy,
    rows: int,
    cols: int,
    res_m: float,
    plane_z: float,
    fill: float = 0.0,
) -> np.ndarray:
    """(rows, cols, C) float32 top-down view of the plane z = plane_z (see `plane_grid`),
    resampled from `image` (H, W, C) through `calib`; what the camera does not see is `fill`."""
    h, w = np.shape(image)[:2]
    if (w, h) != (calib.width, calib.height):
        raise CalibrationError(
            f"the image is {w}x{h} px but the calibration is for {calib.width}x{calib.height}"
        )
    xy = plane_grid(centre_xy, rows, cols, res_m)
    xyz = np.concatenate([xy, np.full(xy.shape[:-1] + (1,), plane_z)], axis=-1)
    return bilinear(image, calib.project(xyz), fill)
