"""vision/views.py: the two views' grids on the board-top plane, resampled through the camera
exactly where the grid says, and standardized per view."""

from __future__ import annotations

import json

import numpy as np

from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.vision.views import ViewConfig, coarse_view, fine_view, standardize
from mjx_peg.world import constants

CALIB = CameraCalibration.from_mujoco(
    (0.35, 0.0, 0.9), np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]]), 45.0, 1280, 960
)
# Each pixel holds its own (u, v): bilinear resampling of a linear image is exact.
RAMP = np.stack([*np.meshgrid(np.arange(1280.0), np.arange(960.0)), np.zeros((960, 1280))], -1)


def test_coarse_grid_by_hand_and_its_inverse():
    config = ViewConfig()
    top_left = config.coarse_to_world([0.0, 0.0])
    np.testing.assert_allclose(top_left, [0.414 + 64 * 0.006, 108 * 0.006], atol=1e-15)
    np.testing.assert_allclose(config.coarse_to_world([64.0, 108.0]), [0.414, 0.0], atol=1e-15)
    rc = np.random.default_rng(0).uniform(0, 128, size=(10, 2))
    np.testing.assert_allclose(config.world_to_coarse(config.coarse_to_world(rc)), rc, atol=1e-12)
    assert config.coarse_cells == (16, 27)
    assert ViewConfig.from_json(json.loads(json.dumps(config.to_json()))) == config
    assert config.plane_z == constants.HOLE_DEPTH


def test_each_view_pixel_is_the_camera_pixel_of_its_grid_point():
    """Coarse pixel (r, c) samples the image where the camera sees coarse_to_world(r + 0.5,
    c + 0.5) on the board top, up = world +x, right = world -y; fine pixels are 1.25 mm apart;
    what the camera does not see is 0."""
    config = ViewConfig()
    coarse = coarse_view(RAMP, CALIB, config)
    assert coarse.shape == (128, 216, 3) and coarse.dtype == np.float32
    rows, cols = np.meshgrid(np.arange(128) + 0.5, np.arange(216) + 0.5, indexing="ij")
    xy = config.coarse_to_world(np.stack([rows, cols], -1))
    uv = CALIB.project(np.concatenate([xy, np.full((128, 216, 1), config.plane_z)], -1))
    seen = (uv[..., 0] <= 1279) & (uv[..., 1] <= 959) & (uv.min(-1) >= 0)
    assert 0.3 < seen.mean() < 1.0  # part of the workspace is out of this camera's view
    np.testing.assert_allclose(coarse[seen][:, :2], uv[seen], atol=2e-3)
    np.testing.assert_array_equal(coarse[~seen], 0.0)
    fine = fine_view(RAMP, CALIB, (0.5, 0.1), config)
    assert fine.shape == (112, 112, 3)
    corner = [0.5 + 55.5 * 0.00125, 0.1 + 55.5 * 0.00125, config.plane_z]  # pixel (0, 0)
    np.testing.assert_allclose(fine[0, 0, :2], CALIB.project(np.array(corner)), atol=2e-3)
    step = CALIB.metres_per_pixel(config.plane_z)
    for down, right in ((1, 0), (0, 1)):  # neighbours: 1.25 mm apart on the board top
        pixels = np.linalg.norm(fine[down, right, :2] - fine[0, 0, :2])
        np.testing.assert_allclose(pixels, 0.00125 / step, rtol=0.01)


def test_standardize_removes_channel_means_and_scales_by_the_std_plus_4():
    rng = np.random.default_rng(1)
    views = rng.uniform(0, 255, size=(2, 8, 6, 3)) + np.array([10.0, 50.0, 90.0])
    out = standardize(views)
    assert out.dtype == np.float32 and out.shape == views.shape
    np.testing.assert_allclose(out.mean(axis=(1, 2)), 0.0, atol=1e-5)
    centred = views - views.mean(axis=(1, 2), keepdims=True)
    std = np.sqrt((centred**2).mean(axis=(1, 2, 3)))
    np.testing.assert_allclose(np.sqrt((out**2).mean(axis=(1, 2, 3))), std / (std + 4), rtol=1e-5)
    flat = standardize(np.full((4, 4, 3), 120.0))  # one colour: nothing left, no division by 0
    np.testing.assert_array_equal(flat, 0.0)
