"""vision/randomize.py: boards drawn over the task's workspace, views drawn by seed within their
stated ranges, a view written into the model where the draw says, and the sensor's stages."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.vision import randomize
from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.world import scene
from mjx_peg.world.task import TaskConfig


def test_boards_cover_the_workspace_sector_uniformly_in_area():
    rng, task = np.random.default_rng(0), TaskConfig()
    boards = [randomize.sample_board(rng, task=task) for _ in range(2000)]
    radius = np.hypot([b["x"] for b in boards], [b["y"] for b in boards])
    angle = np.arctan2([b["y"] for b in boards], [b["x"] for b in boards])
    assert task.workspace_radius[0] <= radius.min() and radius.max() <= task.workspace_radius[1]
    assert task.workspace_angle[0] <= angle.min() and angle.max() <= task.workspace_angle[1]
    r0, r1 = task.workspace_radius  # uniform in area: half the boards beyond the mid-area radius
    assert abs(np.mean(radius > math.sqrt((r0**2 + r1**2) / 2)) - 0.5) < 0.04
    assert {b["shape"] for b in boards} == {"circle", "square", "triangle"}  # the paper's
    assert {round(1000 * b["size"]) for b in boards} == {25, 50, 60}
    assert all(0 <= b["yaw"] < 2 * math.pi for b in boards)
    again = np.random.default_rng(0)
    assert [randomize.sample_board(again) for _ in range(2)] == boards[:2]


@pytest.mark.parametrize("condition", randomize.CONDITIONS)
def test_a_view_is_drawn_by_seed_within_its_ranges(condition):
    board = randomize.sample_board(np.random.default_rng(1))
    view = randomize.sample_view(np.random.default_rng(2), board, condition)
    assert view == randomize.sample_view(np.random.default_rng(2), board, condition)
    calib = CameraCalibration.from_json(view["calibration"])
    true = CameraCalibration.from_json(view["camera_true"])
    offset = np.linalg.norm(true.t_base_camera - calib.t_base_camera)
    if condition == "camera-off":
        assert offset == pytest.approx(randomize.CAMERA_OFF_M, rel=1e-9)
    else:
        assert np.abs(true.t_base_camera - calib.t_base_camera).max() <= randomize.CALIB_ERROR_M
    scale = randomize.DARK_FACTOR if condition == "dark" else 1.0
    assert 0.15 * scale <= view["lights"]["head_ambient"] <= 0.45 * scale
    assert len(view["distractors"]) <= 8 and view["condition"] == condition
    for d in view["distractors"]:  # off the board
        assert math.hypot(d["pos"][0] - board["x"], d["pos"][1] - board["y"]) > 0.1


def test_an_unknown_condition_is_one_line():
    board = randomize.sample_board(np.random.default_rng(1))
    with pytest.raises(UsageError, match="unknown condition 'foggy': choose from nominal"):
        randomize.sample_view(np.random.default_rng(2), board, "foggy")


def test_a_view_is_written_into_the_model_as_drawn():
    rng = np.random.default_rng(3)
    board = dict(randomize.sample_board(rng), shape="square", size=0.05)
    view = randomize.sample_view(rng, board)
    view["distractors"] = view["distractors"][:1]
    model = randomize.load_vision_model("square", 0.05)
    data = mujoco.MjData(model)
    randomize.apply_view(model, data, board, view)
    ids = scene.scene_ids(model)
    np.testing.assert_allclose(data.xpos[ids.board_body][:2], [board["x"], board["y"]], atol=1e-12)
    np.testing.assert_allclose(data.qpos[ids.qpos_adr], view["arm_q"])
    camera = model.camera(randomize.CAMERA).id
    true = CameraCalibration.from_json(view["camera_true"])
    np.testing.assert_allclose(data.cam_xpos[camera], true.t_base_camera, atol=1e-12)
    frame = data.cam_xmat[camera].reshape(3, 3) @ np.diag([1.0, -1.0, -1.0])  # MuJoCo -> OpenCV
    np.testing.assert_allclose(frame, true.R_base_camera, atol=1e-9)
    placed = view["distractors"][0]["name"] if view["distractors"] else None
    for kind, count in randomize.N_DISTRACTORS.items():
        for k in range(count):
            name = f"vd_{kind}{k}"
            z = model.body(name).pos[2]
            assert (z == randomize.PARK_Z) == (name != placed), name
    fresh = randomize.load_vision_model("square", 0.05)  # every load is its own copy
    assert not np.allclose(fresh.cam_pos[camera], model.cam_pos[camera])


def test_the_sensor_stages():
    """Unit gain, white balance and gamma, no blur and no noise: the frame as rendered; gain 2
    doubles it up to 255; the noise is the seed's."""
    rgb = np.random.default_rng(4).integers(0, 256, (16, 12, 3), np.uint8)
    clean = dict(gain=1.0, white_balance=[1.0, 1.0, 1.0], gamma=1.0, blur_px=0.0, read_noise=0.0,
                 shot_noise=0.0, seed=5)  # fmt: skip
    np.testing.assert_array_equal(randomize.postprocess(rgb, clean), rgb)
    doubled = randomize.postprocess(rgb, dict(clean, gain=2.0))
    np.testing.assert_array_equal(doubled, np.minimum(2 * rgb.astype(int), 255))
    noisy = dict(clean, read_noise=3.0, shot_noise=0.5)
    a, b = randomize.postprocess(rgb, noisy), randomize.postprocess(rgb, noisy)
    np.testing.assert_array_equal(a, b)
    assert 2.0 < np.std(a.astype(float) - rgb) < 4.0
    assert not np.array_equal(a, randomize.postprocess(rgb, dict(noisy, seed=6)))
