"""vision/camera.py: the calibration's projection, its JSON round trip and lens distortion."""

from __future__ import annotations

import json

import numpy as np

from mjx_peg.vision.camera import CameraCalibration


def test_calibration_round_trip_and_distortion():
    calib = CameraCalibration.from_mujoco(
        (0.35, 0.0, 1.3),
        np.diag([1.0, 1.0, 1.0]) @ np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1.0]]).T,
        45.0,
        1280,
        960,
    )
    again = CameraCalibration.from_json(json.loads(json.dumps(calib.to_json())))
    points = np.array([[0.5, 0.2, 0.08], [0.3, -0.4, 0.0]])
    np.testing.assert_allclose(again.project(points), calib.project(points), atol=1e-9)
    np.testing.assert_allclose(
        calib.unproject_to_plane(calib.project(points), 0.08)[0], points[0], atol=1e-9
    )
    doc = calib.to_json() | {"distortion": [-0.1, 0.02, 1e-3, -1e-3, 0.0]}
    bent = CameraCalibration.from_json(doc)
    uv = bent.project(points)
    assert np.abs(uv - calib.project(points)).max() > 1.0
    np.testing.assert_allclose(bent.unproject_to_plane(uv[1], 0.0), points[1], atol=1e-7)
