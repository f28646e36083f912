"""vision/dataset.py: labels against the rendered geometry, renders deterministic by seed.
Small renders (320 x 240)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjx_peg.vision import dataset
from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.world import constants

PIXEL_TOL = 1.0  # px: a label's projected hole centre vs the rendered marker
SMALL = dict(width=320, height=240, shapes=("square",), sizes_mm=(50.0,))


def _marker_render(board: dict, view: dict, width: int, height: int) -> np.ndarray:
    """Raw render with the `hole` site as a green sphere at the board-top hole centre."""
    with dataset.Renderer(width, height) as renderer:
        model, data, ren = renderer.scene(board["shape"], board["size"])
        dataset.apply_view(model, data, board, view)
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "hole")
        model.site_pos[site] = (0.0, 0.0, constants.HOLE_DEPTH)
        model.site_sameframe[site] = 0  # the compiler marked it "at the body origin"
        model.site_size[site] = 0.008
        model.site_rgba[site] = (0.0, 1.0, 0.0, 1.0)
        mujoco.mj_forward(model, data)
        option = mujoco.MjvOption()
        option.sitegroup[4] = 1
        ren.update_scene(data, camera="birdseye", scene_option=option)
        return np.array(ren.render(), dtype=np.int32)


@pytest.mark.parametrize(("shape", "seed"), [("square", 3), ("triangle", 4)])
def test_label_is_the_rendered_hole_centre(shape, seed):
    config = dataset.SplitConfig(count=1, seed=seed, width=640, height=480, shapes=(shape,))
    board, view = dataset.draw(config, 0)
    view["distractors"] = []
    view["lights"].update(head_ambient=0.6, head_diffuse=0.6, key_shadow=False)
    view["board_look"]["rgb"] = [0.2, 0.2, 0.8]
    view["table"].update(rgb=[0.9, 0.3, 0.3], texture="plain")
    img = _marker_render(board, view, 640, 480)
    green = (img[..., 1] > 200) & (img[..., 0] < 80) & (img[..., 2] < 80)
    v, u = np.nonzero(green)
    assert u.size > 10, "the marker is not visible"
    label = dataset.make_label(board, view)
    assert np.hypot(u.mean() - label["hole_px"][0], v.mean() - label["hole_px"][1]) < PIXEL_TOL
    # The calibration a user has is within the stated error of the true camera.
    calib = CameraCalibration.from_json(label["calibration"])
    true = CameraCalibration.from_json(view["camera_true"])
    assert np.abs(calib.t_base_camera - true.t_base_camera).max() <= 0.001 + 1e-12
    top = np.array([board["x"], board["y"], constants.HOLE_DEPTH])
    back = calib.unproject_to_plane(true.project(top), constants.HOLE_DEPTH)
    assert np.hypot(*(back - top)[:2]) < 0.004  # 1 mm + 0.05 deg about each axis


def test_renders_are_deterministic_by_seed(tmp_path):
    config = dataset.SplitConfig(count=2, seed=5, **SMALL)
    assert dataset.draw(config, 1) == dataset.draw(config, 1)
    dataset.render_split(tmp_path / "a", config, progress=False)
    dataset.render_split(tmp_path / "b", config, progress=False)
    for name in ("000000.png", "000001.png", "000001.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    (tmp_path / "a" / "000001.json").unlink()  # resume: only the missing image is redone
    assert dataset.render_split(tmp_path / "a", config, progress=False) == 1
    assert (tmp_path / "a" / "000001.png").read_bytes() == (
        tmp_path / "b" / "000001.png"
    ).read_bytes()
    other = dataset.SplitConfig(count=1, seed=6, **SMALL)
    assert dataset.draw(other, 0) != dataset.draw(config, 0)
