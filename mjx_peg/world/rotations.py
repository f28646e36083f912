"""Rotations: quaternions (w, x, y, z), rotation vectors and matrices, batched over `...`.

Written once over the array-API namespace of the inputs (NumPy 2 or JAX, tracers included); this
module imports neither numpy nor jax. Every function stays finite, with finite gradients, at the
identity (safe norms with Taylor branches below a small angle) and near a half turn (the matrix
to quaternion map picks the best-conditioned of Shepperd's four branches). Conventions follow
CONVENTIONS.md: quaternions are (w, x, y, z) and act as R(q) v = q v q*.
"""

from __future__ import annotations

from mjx_peg.array_api import namespace_of

# Below this squared angle (rad^2) the Taylor branches are used; their error is O(angle^4) ~ 1e-16.
_SMALL_ANGLE_SQ = 1e-8


def _vec_sq(v):
    """(...,) squared norm of the last axis."""
    xp = namespace_of(v)
    return xp.sum(v * v, axis=-1)


def skew(v):
    """(..., 3, 3) cross-product matrix [v]x of v (..., 3): [v]x u = v x u."""
    xp = namespace_of(v)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    o = xp.zeros_like(x)
    return xp.stack(
        [
            xp.stack([o, -z, y], axis=-1),
            xp.stack([z, o, -x], axis=-1),
            xp.stack([-y, x, o], axis=-1),
        ],
        axis=-2,
    )


def quat_mul(q1, q2):
    """(..., 4) Hamilton product q1 q2 of quaternions (..., 4) (w, x, y, z)."""
    xp = namespace_of(q1, q2)
    w1, x1, y1, z1 = (q1[..., i] for i in range(4))
    w2, x2, y2, z2 = (q2[..., i] for i in range(4))
    return xp.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def quat_conj(q):
    """(..., 4) conjugate (w, -x, -y, -z) of q (..., 4); the inverse of a unit quaternion."""
    xp = namespace_of(q)
    return xp.concat([q[..., :1], -q[..., 1:]], axis=-1)


def quat_from_rotvec(rotvec):
    """(..., 4) unit quaternion of rotation vector (..., 3): (cos(a/2), sin(a/2) v/a), a = |v|."""
    xp = namespace_of(rotvec)
    angle_sq = _vec_sq(rotvec)
    small = angle_sq < _SMALL_ANGLE_SQ
    angle = xp.sqrt(xp.where(small, 1.0, angle_sq))  # safe norm: finite value and gradient at 0
    half = 0.5 * angle
    w = xp.where(small, 1.0 - angle_sq / 8.0, xp.cos(half))
    k = xp.where(small, 0.5 - angle_sq / 48.0, xp.sin(half) / angle)  # sin(a/2) / a
    return xp.concat([w[..., None], k[..., None] * rotvec], axis=-1)


def rotvec_from_quat(quat):
    """(..., 3) shortest rotation vector (angle in [0, pi]) of quaternion (..., 4); q and -q alike.

    theta = 2 atan2(|v|, w) v / |v| after flipping q so that w >= 0; scale-invariant in q.
    """
    xp = namespace_of(quat)
    sign = xp.where(quat[..., :1] < 0, -1.0, 1.0)
    q = quat * sign
    w, v = q[..., 0], q[..., 1:]
    n_sq = _vec_sq(v)
    w_sq = w * w
    # Small-angle branch relative to the quaternion's scale: |v|/w < 1e-4.
    small = n_sq < _SMALL_ANGLE_SQ * w_sq
    n = xp.sqrt(xp.where(small, 1.0, n_sq))
    w_safe = xp.where(small, w, 1.0)
    # 2 atan2(n, w) / n = (2 / w) (1 - n^2 / (3 w^2) + ...) for n << w.
    factor = xp.where(
        small, 2.0 / w_safe * (1.0 - n_sq / (3.0 * w_safe * w_safe)), 2.0 * xp.atan2(n, w) / n
    )
    return factor[..., None] * v


def matrix_from_quat(quat):
    """(..., 3, 3) rotation matrix of quaternion (..., 4) (w, x, y, z); need not be normalized."""
    xp = namespace_of(quat)
    w, x, y, z = (quat[..., i] for i in range(4))
    s = 2.0 / _vec_sq(quat)
    xx, yy, zz = s * x * x, s * y * y, s * z * z
    xy, xz, yz = s * x * y, s * x * z, s * y * z
    wx, wy, wz = s * w * x, s * w * y, s * w * z
    return xp.stack(
        [
            xp.stack([1.0 - yy - zz, xy - wz, xz + wy], axis=-1),
            xp.stack([xy + wz, 1.0 - xx - zz, yz - wx], axis=-1),
            xp.stack([xz - wy, yz + wx, 1.0 - xx - yy], axis=-1),
        ],
        axis=-2,
    )


def quat_from_matrix(mat):
    """(..., 4) unit quaternion with w >= 0 of rotation matrix (..., 3, 3).

    Shepperd's method, branch-free: all four candidates (from 4 w^2, 4 x^2, 4 y^2, 4 z^2 = 1 +/-
    trace terms) are computed with safe square roots and the largest-denominator one is selected.
    """
    xp = namespace_of(mat)
    r = [[mat[..., i, j] for j in range(3)] for i in range(3)]
    t = xp.stack(
        [
            1.0 + r[0][0] + r[1][1] + r[2][2],
            1.0 + r[0][0] - r[1][1] - r[2][2],
            1.0 - r[0][0] + r[1][1] - r[2][2],
            1.0 - r[0][0] - r[1][1] + r[2][2],
        ],
        axis=-1,
    )
    d21, d02, d10 = r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]
    s01, s02, s12 = r[0][1] + r[1][0], r[0][2] + r[2][0], r[1][2] + r[2][1]
    candidates = xp.stack(
        [
            xp.stack([t[..., 0], d21, d02, d10], axis=-1),
            xp.stack([d21, t[..., 1], s01, s02], axis=-1),
            xp.stack([d02, s01, t[..., 2], s12], axis=-1),
            xp.stack([d10, s02, s12, t[..., 3]], axis=-1),
        ],
        axis=-2,
    )  # (..., 4, 4): candidate k = 2 sqrt(t_k) q
    scale = 0.5 / xp.sqrt(xp.maximum(t, 1e-12))  # (..., 4); only the selected one is used
    best = xp.argmax(t, axis=-1)
    onehot = xp.astype(xp.arange(4) == best[..., None], mat.dtype)
    q = xp.sum((onehot * scale)[..., None] * candidates, axis=-2)
    q = q / xp.sqrt(_vec_sq(q))[..., None]
    return q * xp.where(q[..., :1] < 0, -1.0, 1.0)


def matrix_from_rotvec(rotvec):
    """(..., 3, 3) Rodrigues: R = I + sin(a)/a [v]x + (1 - cos a)/a^2 [v]x^2, a = |v|."""
    xp = namespace_of(rotvec)
    angle_sq = _vec_sq(rotvec)
    small = angle_sq < _SMALL_ANGLE_SQ
    angle = xp.sqrt(xp.where(small, 1.0, angle_sq))
    a = xp.where(small, 1.0 - angle_sq / 6.0, xp.sin(angle) / angle)
    b = xp.where(small, 0.5 - angle_sq / 24.0, (1.0 - xp.cos(angle)) / (angle * angle))
    k = skew(rotvec)
    eye = xp.eye(3, dtype=rotvec.dtype)
    return eye + a[..., None, None] * k + b[..., None, None] * (k @ k)


def rotvec_from_matrix(mat):
    """(..., 3) shortest rotation vector (angle in [0, pi]) of rotation matrix (..., 3, 3)."""
    return rotvec_from_quat(quat_from_matrix(mat))


def quat_from_yaw(yaw):
    """(..., 4) quaternion (cos(yaw/2), 0, 0, sin(yaw/2)) of a turn by yaw (...,) rad about z."""
    xp = namespace_of(yaw)
    z = xp.zeros_like(yaw)
    return xp.stack([xp.cos(0.5 * yaw), z, z, xp.sin(0.5 * yaw)], axis=-1)


def tool_down_rotation(yaw):
    """(..., 3, 3) tool-down orientation whose x axis is at `yaw` (...,) rad about world z.

    R = Rz(yaw) Rx(pi): the tool z axis points along world -z (CONVENTIONS.md: the goal
    orientation of the tcp over a hole of yaw `yaw`).
    """
    xp = namespace_of(yaw)
    c, s = xp.cos(yaw), xp.sin(yaw)
    z, o = xp.zeros_like(c), xp.ones_like(c)
    rows = [
        xp.stack([c, s, z], axis=-1),
        xp.stack([s, -c, z], axis=-1),
        xp.stack([z, z, -o], axis=-1),
    ]
    return xp.stack(rows, axis=-2)


__all__ = [
    "matrix_from_quat",
    "matrix_from_rotvec",
    "namespace_of",
    "quat_conj",
    "quat_from_matrix",
    "quat_from_rotvec",
    "quat_from_yaw",
    "quat_mul",
    "rotvec_from_matrix",
    "rotvec_from_quat",
    "skew",
    "tool_down_rotation",
]
