"""world/render.py: a frame of the scene headless (MUJOCO_GL=egl, as tests/conftest.py sets it)
at the size asked, its PNG, and one-line refusals of a camera, a size and a back-end."""

from __future__ import annotations

import os
import subprocess
import sys

import mujoco
import numpy as np
import pytest
from matplotlib import image

from mjx_peg.errors import UsageError
from mjx_peg.world import render, scene


@pytest.fixture(scope="module")
def square():
    model = scene.load_model("square", 0.05)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def test_a_frame_and_its_png_are_the_size_asked(square, tmp_path):
    model, data = square
    rgb = render.render_rgb(model, data, "birdseye", 160, 120)
    assert rgb.shape == (120, 160, 3) and rgb.dtype == np.uint8
    assert rgb.reshape(-1, 3).std(axis=0).max() > 10  # a scene, not one colour
    again = render.render_rgb(model, data, model.camera("birdseye").id, 160, 120)
    np.testing.assert_array_equal(again, rgb)  # by name or id: the same camera, the same frame
    path = render.write_png(tmp_path / "sub" / "frame.png", model, data, "birdseye", 160, 120)
    assert path == tmp_path / "sub" / "frame.png"
    read = image.imread(path)
    assert read.shape[:2] == (120, 160)
    np.testing.assert_array_equal(np.round(read[..., :3] * 255).astype(np.uint8), rgb)


def test_a_camera_or_size_the_model_cannot_give_is_one_line(square):
    model, data = square
    with pytest.raises(UsageError, match="unknown camera 'top': valid cameras are birdseye"):
        render.render_rgb(model, data, "top")
    with pytest.raises(UsageError, match="image size 2000x100 must be within the offscreen"):
        render.render_rgb(model, data, width=2000, height=100)
    with pytest.raises(UsageError, match="image size 0x100"):
        render.render_rgb(model, data, width=0, height=100)


def test_a_disabled_back_end_is_one_render_error_before_any_work():
    code = (
        "from mjx_peg.world import render\n"
        "try:\n"
        "    render.check_backend()\n"
        "except render.RenderError as e:\n"
        "    print(e)\n"
    )
    env = {**os.environ, "MUJOCO_GL": "disable"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "rendering is disabled (MUJOCO_GL=disable); set MUJOCO_GL=egl\n"
    render.check_backend()  # here it renders
