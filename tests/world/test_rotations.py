"""Rotations against scipy.spatial.transform.Rotation (which orders quaternions x, y, z, w)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mjx_peg.world import rotations as rot

TOL = 1e-12


def _scipy_quat(r: Rotation) -> np.ndarray:
    """(..., 4) (w, x, y, z) from scipy's (x, y, z, w)."""
    q = r.as_quat()
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


def _same_quat(q1, q2, tol):
    """q and -q are the same rotation."""
    err = np.minimum(np.abs(q1 - q2).max(axis=-1), np.abs(q1 + q2).max(axis=-1))
    assert err.max() < tol, err.max()


def _rotvecs(rng):
    """(N, 3): random, zero, tiny, exactly pi and just below pi, along random axes."""
    axes = rng.normal(size=(60, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate(
        [
            rng.uniform(0.0, np.pi, 30),
            [0.0, 1e-12, 1e-9, 1e-6, 1e-4, 1e-2],
            [np.pi - 1e-12, np.pi - 1e-9, np.pi - 1e-6, np.pi - 1e-3, np.pi],
            rng.uniform(np.pi - 0.1, np.pi, 19),
        ]
    )
    return axes * angles[:, None]


@pytest.fixture
def rng():
    return np.random.default_rng(0)


def test_quat_from_rotvec_matches_scipy(rng):
    v = _rotvecs(rng)
    _same_quat(rot.quat_from_rotvec(v), _scipy_quat(Rotation.from_rotvec(v)), TOL)


def test_matrix_from_rotvec_and_quat_match_scipy(rng):
    v = _rotvecs(rng)
    expected = Rotation.from_rotvec(v).as_matrix()
    np.testing.assert_allclose(rot.matrix_from_rotvec(v), expected, atol=TOL)
    np.testing.assert_allclose(rot.matrix_from_quat(rot.quat_from_rotvec(v)), expected, atol=TOL)


def test_quat_from_matrix_matches_scipy(rng):
    mats = Rotation.from_rotvec(_rotvecs(rng)).as_matrix()
    q = rot.quat_from_matrix(mats)
    assert np.all(q[:, 0] >= 0)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=TOL)
    _same_quat(q, _scipy_quat(Rotation.from_matrix(mats)), 1e-9)


def test_rotvec_round_trips_including_zero_and_pi(rng):
    v = _rotvecs(rng)
    # Near pi the rotation vector is only defined up to sign: compare rotations, and angles.
    for back in (
        rot.rotvec_from_quat(rot.quat_from_rotvec(v)),
        rot.rotvec_from_matrix(rot.matrix_from_rotvec(v)),
    ):
        np.testing.assert_allclose(
            np.linalg.norm(back, axis=-1), np.linalg.norm(v, axis=-1), atol=1e-9
        )
        np.testing.assert_allclose(
            rot.matrix_from_rotvec(back), rot.matrix_from_rotvec(v), atol=1e-9
        )
        below = np.linalg.norm(v, axis=-1) < np.pi - 1e-3
        np.testing.assert_allclose(back[below], v[below], atol=1e-12)


def test_rotvec_from_matrix_matches_scipy_below_pi(rng):
    v = _rotvecs(rng)
    keep = np.linalg.norm(v, axis=-1) < np.pi - 1e-6
    mats = Rotation.from_rotvec(v[keep]).as_matrix()
    np.testing.assert_allclose(
        rot.rotvec_from_matrix(mats), Rotation.from_matrix(mats).as_rotvec(), atol=1e-9
    )


def test_rotvec_from_quat_treats_q_and_minus_q_alike(rng):
    q = _scipy_quat(Rotation.random(50, random_state=1))
    np.testing.assert_allclose(rot.rotvec_from_quat(q), rot.rotvec_from_quat(-q), atol=TOL)
    assert np.all(np.linalg.norm(rot.rotvec_from_quat(q), axis=-1) <= np.pi + TOL)


def test_identity_and_tiny_angles_exact():
    assert np.array_equal(rot.rotvec_from_quat(np.array([1.0, 0, 0, 0])), np.zeros(3))
    assert np.array_equal(rot.rotvec_from_matrix(np.eye(3)), np.zeros(3))
    assert np.array_equal(rot.quat_from_rotvec(np.zeros(3)), np.array([1.0, 0, 0, 0]))
    assert np.array_equal(rot.matrix_from_rotvec(np.zeros(3)), np.eye(3))
    tiny = np.array([1e-10, -2e-10, 3e-10])
    np.testing.assert_allclose(rot.rotvec_from_quat(rot.quat_from_rotvec(tiny)), tiny, rtol=1e-12)


def test_quat_mul_conj_group_axioms(rng):
    r1, r2 = Rotation.random(20, random_state=2), Rotation.random(20, random_state=3)
    q1, q2 = _scipy_quat(r1), _scipy_quat(r2)
    _same_quat(rot.quat_mul(q1, q2), _scipy_quat(r1 * r2), TOL)
    np.testing.assert_allclose(
        rot.matrix_from_quat(rot.quat_mul(q1, q2)),
        rot.matrix_from_quat(q1) @ rot.matrix_from_quat(q2),
        atol=TOL,
    )
    _same_quat(rot.quat_mul(q1, rot.quat_conj(q1)), np.tile([1.0, 0, 0, 0], (20, 1)), TOL)
    q3 = _scipy_quat(Rotation.random(20, random_state=4))
    np.testing.assert_allclose(
        rot.quat_mul(rot.quat_mul(q1, q2), q3), rot.quat_mul(q1, rot.quat_mul(q2, q3)), atol=TOL
    )


def test_quat_from_yaw_matches_scipy():
    yaw = np.linspace(-np.pi, np.pi, 13)
    _same_quat(rot.quat_from_yaw(yaw), _scipy_quat(Rotation.from_euler("z", yaw[:, None])), TOL)


def test_batched_leading_dims(rng):
    v = rng.normal(size=(2, 3, 4, 3))
    assert rot.quat_from_rotvec(v).shape == (2, 3, 4, 4)
    assert rot.matrix_from_rotvec(v).shape == (2, 3, 4, 3, 3)
    assert rot.rotvec_from_matrix(rot.matrix_from_rotvec(v)).shape == (2, 3, 4, 3)
    np.testing.assert_allclose(
        rot.matrix_from_rotvec(v).reshape(-1, 3, 3),
        Rotation.from_rotvec(v.reshape(-1, 3)).as_matrix(),
        atol=TOL,
    )


def test_skew_is_cross_product(rng):
    a, b = rng.normal(size=(2, 10, 3))
    np.testing.assert_allclose((rot.skew(a) @ b[..., None])[..., 0], np.cross(a, b), atol=TOL)
