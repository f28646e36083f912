"""Headless rendering helpers: an RGB frame from a model/data and a camera, and a PNG writer.

The OpenGL back-end is chosen by `gl.choose_backend()` (headless `egl` without a display). A
back-end that cannot make a context here (disabled, no display, no library) is one ValueError
line (`RenderError`); `check_backend()` finds that out before a command does any work.
"""

from __future__ import annotations

import os
import pathlib
import warnings

from mjx_peg.errors import UsageError
from mjx_peg.world import gl

gl.choose_backend()

import mujoco  # noqa: E402
import numpy as np  # noqa: E402


class RenderError(UsageError):
    """MuJoCo cannot render with this process's MUJOCO_GL (one line)."""


def _renderer(model: mujoco.MjModel, height: int, width: int) -> mujoco.Renderer:
    backend = os.environ.get("MUJOCO_GL", "")
    if gl.is_disabled():
        raise RenderError(f"rendering is disabled (MUJOCO_GL={backend}); set MUJOCO_GL=egl")
    try:
        with warnings.catch_warnings():  # glfw warns about a missing display before failing
            warnings.simplefilter("ignore")
            return mujoco.Renderer(model, height, width)
    except (mujoco.FatalError, AttributeError, ImportError, OSError, RuntimeError) as e:
        text = " ".join(str(e).split())[:200]
        raise RenderError(
            f"cannot render with MUJOCO_GL={backend or '(unset)'} ({type(e).__name__}: {text}); "
            "set MUJOCO_GL=egl or osmesa"
        ) from None


def check_backend() -> None:
    """RenderError (one line) unless a frame can be rendered here; costs one tiny context."""
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    with _renderer(model, 16, 16) as renderer:
        renderer.update_scene(mujoco.MjData(model))
        renderer.render()


def render_rgb(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    camera: str | int | mujoco.MjvCamera = "birdseye",
    width: int = 640,
    height: int = 480,
) -> np.ndarray:
    """(height, width, 3) uint8 RGB image of `data` seen from `camera` (name, id or MjvCamera).

    The frame must fit the model's offscreen buffer (<visual><global offwidth/offheight>,
    1280 x 960 in the mjx_peg scenes); the renderer is closed before returning.
    """
    width, height = int(width), int(height)
    max_w, max_h = int(model.vis.global_.offwidth), int(model.vis.global_.offheight)
    if not (0 < width <= max_w and 0 < height <= max_h):
        raise UsageError(
            f"image size {width}x{height} must be within the offscreen buffer {max_w}x{max_h}"
        )
    if isinstance(camera, str) and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera) < 0:
        names = [model.camera(i).name for i in range(model.ncam)]
        raise UsageError(
            f"unknown camera {camera!r}: valid cameras are {', '.join(names) or 'none'}"
        )
    with _renderer(model, height, width) as renderer:
        renderer.update_scene(data, camera=camera)
        return np.array(renderer.render(), dtype=np.uint8)


def save_png(path: str | os.PathLike, rgb: np.ndarray) -> pathlib.Path:
    """Write an (H, W, 3) uint8 image as PNG (parent folders created); returns the path."""
    from matplotlib import image  # no pyplot: leaves the caller's backend alone

    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    image.imsave(path, np.asarray(rgb, dtype=np.uint8))
    return path


def write_png(
    path: str | os.PathLike,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    camera: str | int | mujoco.MjvCamera = "birdseye",
    width: int = 640,
    height: int = 480,
) -> pathlib.Path:
    """Render `data` from `camera` and write it to `path` as PNG; returns the path."""
    return save_png(path, render_rgb(model, data, camera, width, height))
