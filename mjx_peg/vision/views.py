"""What the localizer's two networks look at: top-down views of the board-top plane.

NumPy only. Both views are resampled from the camera image through its calibration onto the
plane z = HOLE_DEPTH (the board top, whose height is known, as in the paper), so a pixel is a
fixed size on the table whatever the camera's pose, and the networks work in millimetres:

- coarse: the whole workspace at 6 mm/px (128 x 216 px: x 0.03-0.80 m, y -0.65-0.65 m), for the
  detector that finds the board anywhere (a 25 mm hole is 4 px across: enough to tell a board
  from a hole-less slab);
- fine: 112 x 112 px at 1.25 mm/px (140 mm) around the coarse estimate, for the regressor that
  measures the hole (the 1280 x 960 camera sees the board top at ~1.05 mm/px).

Views are laid out like the camera image (up = world +x, right = world -y; `camera.plane_grid`)
and standardized per view (channel means removed, divided by the overall standard deviation), so
exposure and white balance matter less.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mjx_peg.vision.camera import CameraCalibration, rectify
from mjx_peg.world import constants


@dataclasses.dataclass(frozen=True)
class ViewConfig:
    """The two views' grids on the board-top plane (m)."""

    coarse_centre: tuple[float, float] = (0.414, 0.0)
    coarse_rows: int = 128
    coarse_cols: int = 216
    coarse_res: float = 0.006
    coarse_stride: int = 8  # the detector's output cell = 8 x 8 view pixels (48 mm)
    fine_size: int = 112
    fine_res: float = 0.00125
    plane_z: float = float(constants.HOLE_DEPTH)

    def __post_init__(self):
        import math

        centre = self.coarse_centre
        if not (
            len(centre) == 2 and all(type(v) in (int, float) and math.isfinite(v) for v in centre)
        ):
            raise ValueError("views.coarse_centre is not two numbers")
        for name in ("coarse_rows", "coarse_cols", "coarse_stride", "fine_size"):
            value = getattr(self, name)
            if type(value) is not int or not 1 <= value <= 4096:
                raise ValueError(f"views.{name} is not a whole number of pixels in 1..4096")
        for name in ("coarse_res", "fine_res", "plane_z"):
            value = getattr(self, name)
            if type(value) not in (int, float) or not (math.isfinite(value) and abs(value) < 10):
                raise ValueError(f"views.{name} is not a length in metres")
        if not (self.coarse_res > 0 and self.fine_res > 0):
            raise ValueError("views: a resolution is not positive")

    @classmethod
    def from_json(cls, doc: dict) -> ViewConfig:
        """The ViewConfig of its JSON form; ValueError or TypeError if it is not one."""
        doc = dict(doc)
        doc["coarse_centre"] = tuple(doc["coarse_centre"])
        return cls(**doc)

    def to_json(self) -> dict:
        return {
            f.name: list(v) if isinstance(v := getattr(self, f.name), tuple) else v
            for f in dataclasses.fields(self)
        }

    @property
    def coarse_cells(self) -> tuple[int, int]:
        return self.coarse_rows // self.coarse_stride, self.coarse_cols // self.coarse_stride

    def coarse_to_world(self, rc) -> np.ndarray:
        """(..., 2) world (x, y) of continuous coarse-view coordinates (..., 2) (row, col), where
        (0, 0) is the top-left corner of the view (not a pixel centre)."""
        rc = np.asarray(rc, dtype=np.float64)
        x_top = self.coarse_centre[0] + 0.5 * self.coarse_rows * self.coarse_res
        y_left = self.coarse_centre[1] + 0.5 * self.coarse_cols * self.coarse_res
        return np.stack(
            [x_top - rc[..., 0] * self.coarse_res, y_left - rc[..., 1] * self.coarse_res], -1
        )

    def world_to_coarse(self, xy) -> np.ndarray:
        """Inverse of `coarse_to_world`."""
        xy = np.asarray(xy, dtype=np.float64)
        x_top = self.coarse_centre[0] + 0.5 * self.coarse_rows * self.coarse_res
        y_left = self.coarse_centre[1] + 0.5 * self.coarse_cols * self.coarse_res
        return np.stack(
            [(x_top - xy[..., 0]) / self.coarse_res, (y_left - xy[..., 1]) / self.coarse_res], -1
        )


def coarse_view(image: np.ndarray, calib: CameraCalibration, config: ViewConfig) -> np.ndarray:
    """(rows, cols, 3) float32 raw (0-255) workspace view; unseen pixels are 0."""
    return rectify(
        image,
        calib,
        config.coarse_centre,
        config.coarse_rows,
        config.coarse_cols,
        config.coarse_res,
        config.plane_z,
    )


def fine_view(image: np.ndarray, calib: CameraCalibration, centre_xy, config: ViewConfig):
    """(size, size, 3) float32 raw (0-255) view centred on world `centre_xy`."""
    n = config.fine_size
    return rectify(image, calib, centre_xy, n, n, config.fine_res, config.plane_z)


def standardize(views: np.ndarray) -> np.ndarray:
    """(..., H, W, 3) float32 views, each minus its channel means, over its overall std + 4."""
    views = np.asarray(views, dtype=np.float32)
    mean = views.mean(axis=(-3, -2), keepdims=True)
    centred = views - mean
    std = np.sqrt((centred**2).mean(axis=(-3, -2, -1), keepdims=True))
    return centred / (std + np.float32(4.0))
