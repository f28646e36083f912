"""UR5e kinematics in NumPy: forward kinematics, geometric Jacobian and its time derivative,
analytic inverse kinematics.

Standard DH with Universal Robots' published figures (CONVENTIONS.md): frame i from frame i-1 is
Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i), theta_i = q_i (no offsets). Frame 6 is the flange (tool0);
the tcp is the flange moved `tool_length` along the flange z axis, with the flange's orientation.
Every function is batched over leading dimensions, works in float64 and in the world (= base)
frame. The analytic IK follows the geometry of the UR arm (three parallel joints 2-4 between a
shoulder and a spherical-free wrist), as derived e.g. by Hawkins, "Analytic inverse kinematics for
the Universal Robots UR-5/UR-10 arms" (2013); it is written here by hand (no library offers it
for arrays) and polished with damped Newton steps.
"""

from __future__ import annotations

import functools

import numpy as np

from mjx_peg.errors import UsageError
from mjx_peg.world import constants
from mjx_peg.world.rotations import rotvec_from_matrix, tool_down_rotation

D1, A2, A3, D4, D5, D6 = 0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996  # m
DH_D = np.array([D1, 0.0, 0.0, D4, D5, D6])
DH_A = np.array([0.0, A2, A3, 0.0, 0.0, 0.0])
DH_ALPHA = np.array([np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0])

HOME_Q = np.array(constants.HOME_Q)  # the configuration IK branches are chosen by

IK_TOL_POS = 1e-6  # m: an IK branch is valid when fk(q) is this close to the target...
IK_TOL_ROT = 1e-6  # rad: ...in position and orientation


def wrap_angle(q: np.ndarray) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    q = np.asarray(q, dtype=np.float64)
    return np.pi - np.mod(np.pi - q, 2.0 * np.pi)


def _dh_transform(theta: np.ndarray, i: int) -> np.ndarray:
    """(..., 4, 4) transform of DH frame i+1 in frame i for joint angle theta (...,)."""
    c, s = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(DH_ALPHA[i]), np.sin(DH_ALPHA[i])
    out = np.zeros(theta.shape + (4, 4))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2], out[..., 0, 3] = c, -s * ca, s * sa, DH_A[i] * c
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2], out[..., 1, 3] = s, c * ca, -c * sa, DH_A[i] * s
    out[..., 2, 1], out[..., 2, 2], out[..., 2, 3] = sa, ca, DH_D[i]
    out[..., 3, 3] = 1.0
    return out


def _rigid_inverse(T: np.ndarray) -> np.ndarray:
    """(..., 4, 4) inverse of rigid transforms (..., 4, 4)."""
    out = np.zeros_like(T)
    rot_t = np.swapaxes(T[..., :3, :3], -1, -2)
    out[..., :3, :3] = rot_t
    out[..., :3, 3] = -(rot_t @ T[..., :3, 3:4])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def _check_q(q) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1:] != (6,):
        raise UsageError(f"joint configuration must have shape (..., 6), got {q.shape}")
    return q


def fk_frames(q: np.ndarray) -> np.ndarray:
    """(..., 7, 4, 4) world transforms of DH frames 0 (base) to 6 (flange) for q (..., 6)."""
    q = _check_q(q)
    frames = [np.broadcast_to(np.eye(4), q.shape[:-1] + (4, 4))]
    for i in range(6):  # contiguous operands keep the batched matmul fast
        frames.append(frames[-1] @ _dh_transform(q[..., i].copy(), i))
    return np.stack(frames, axis=-3)


def fk_flange(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flange (tool0) pose: q (..., 6) -> pos (..., 3) m, rot (..., 3, 3), world frame."""
    T = fk_frames(q)[..., 6, :, :]
    return T[..., :3, 3].copy(), T[..., :3, :3].copy()


def fk_tcp(q: np.ndarray, tool_length: float) -> tuple[np.ndarray, np.ndarray]:
    """Tcp pose (flange + tool_length along its z): q (..., 6) -> pos (..., 3), rot (..., 3, 3)."""
    pos, rot = fk_flange(q)
    return pos + tool_length * rot[..., :, 2], rot


def jacobian_tcp(q: np.ndarray, tool_length: float) -> np.ndarray:
    """(..., 6, 6) geometric Jacobian of the tcp in the world frame: rows (v, omega), columns q.

    Column i: (z_{i-1} x (p_tcp - o_{i-1}), z_{i-1}) with frame i-1 the DH frame joint i turns in.
    """
    frames = fk_frames(q)
    z = frames[..., :6, :3, 2]  # (..., 6, 3) joint axes
    o = frames[..., :6, :3, 3]  # (..., 6, 3) points on the axes
    tcp = frames[..., 6, :3, 3] + tool_length * frames[..., 6, :3, 2]
    jac = np.empty(z.shape[:-2] + (6, 6))
    jac[..., :3, :] = np.swapaxes(np.cross(z, tcp[..., None, :] - o), -1, -2)
    jac[..., 3:, :] = np.swapaxes(z, -1, -2)
    return jac


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 3) a x b by components (np.cross is ~10x slower on small arrays)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def tcp_kinematics(
    q: np.ndarray, qd: np.ndarray, tool_length: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(pos (..., 3), rot (..., 3, 3), J (..., 6, 6), dJ/dt (..., 6, 6)) of the tcp at q, qd
    (..., 6), from one pass over the DH frames: `fk_tcp`, `jacobian_tcp` and its derivative.

    Joint i turns about z_{i-1} through o_{i-1}. With w_{i-1} = sum_{j<i} z_{j-1} qd_j the
    angular velocity of DH frame i-1: dz/dt = w x z, do/dt = w x o - sum_{j<i} qd_j z_{j-1} x
    o_{j-1}, dp/dt = J_v qd, and column i of dJ/dt is (dz x (p - o) + z x (dp/dt - do/dt), dz).
    """
    q, qd = _check_q(q), _check_q(qd)
    frames = fk_frames(q)
    z = frames[..., :6, :3, 2]  # (..., 6, 3): z_{i-1}, the axis joint i turns about
    o = frames[..., :6, :3, 3]
    rot = frames[..., 6, :3, :3].copy()
    pos = frames[..., 6, :3, 3] + tool_length * rot[..., :, 2]
    lever = pos[..., None, :] - o
    spin = z * qd[..., None]  # (..., 6, 3) z_{j-1} qd_j
    omega = np.cumsum(spin, axis=-2) - spin  # exclusive: the joints before joint i
    moment = _cross(spin, o)
    o_vel = _cross(omega, o) - (np.cumsum(moment, axis=-2) - moment)
    tcp_vel = np.sum(_cross(spin, lever), axis=-2, keepdims=True)
    z_dot = _cross(omega, z)
    jac = np.concatenate([_cross(z, lever), z], axis=-1)
    jac_dot = np.concatenate([_cross(z_dot, lever) + _cross(z, tcp_vel - o_vel), z_dot], axis=-1)
    return pos, rot, np.swapaxes(jac, -1, -2), np.swapaxes(jac_dot, -1, -2)


def jacobian_dot_tcp(q: np.ndarray, qd: np.ndarray, tool_length: float) -> np.ndarray:
    """(..., 6, 6) time derivative of `jacobian_tcp` along the joint velocity qd (..., 6)."""
    return tcp_kinematics(q, qd, tool_length)[3]


def condition_number(
    q: np.ndarray, tool_length: float, block: str = "full", length_scale: float = 1.0
) -> np.ndarray:
    """(...,) 2-norm condition number of the tcp Jacobian at q (..., 6).

    block "full": the 6x6 Jacobian with the linear rows divided by `length_scale` (m), so that the
    linear and angular rows share a unit; it grows without bound at the shoulder, elbow and wrist
    singularities. The task sampler bounds "full" with length_scale 1 m
    (`TaskConfig.max_condition`).
    block "position": the 3x6 linear block, how evenly the joints move the tcp. With a tool
    offset it stays well conditioned at the elbow and wrist singularities (the wrist joints still
    move the tcp), so it is reported for information, not used as a singularity bound.
    """
    jac = jacobian_tcp(q, tool_length)
    if block == "position":
        jac = jac[..., :3, :]
    elif block == "full":
        jac = np.concatenate([jac[..., :3, :] / length_scale, jac[..., 3:, :]], axis=-2)
    else:
        raise UsageError(f"unknown block {block!r}: choose from position, full")
    sv = np.linalg.svd(jac, compute_uv=False)
    with np.errstate(divide="ignore"):
        return sv[..., 0] / sv[..., -1]


def pose_error(
    q: np.ndarray, pos: np.ndarray, rot: np.ndarray, tool_length: float
) -> tuple[np.ndarray, np.ndarray]:
    """Tcp error of q against a target: (position error (...,) m, orientation error (...,) rad)."""
    p, r = fk_tcp(q, tool_length)
    dp = np.linalg.norm(np.asarray(pos) - p, axis=-1)
    dr = np.linalg.norm(rotvec_from_matrix(np.asarray(rot) @ np.swapaxes(r, -1, -2)), axis=-1)
    return dp, dr


def refine_ik(
    q: np.ndarray,
    pos: np.ndarray,
    rot: np.ndarray,
    tool_length: float,
    steps: int = 2,
    damping: float = 1e-9,
) -> np.ndarray:
    """Damped Newton (least-squares) steps on q (..., 6) toward the tcp target pos (..., 3), rot."""
    q = np.array(q, dtype=np.float64)
    eye = np.eye(6)
    for _ in range(steps):
        p, r = fk_tcp(q, tool_length)
        err = np.concatenate(
            [pos - p, rotvec_from_matrix(rot @ np.swapaxes(r, -1, -2))], axis=-1
        )  # (..., 6) world frame
        jac = jacobian_tcp(q, tool_length)
        jjt = jac @ np.swapaxes(jac, -1, -2) + damping**2 * eye
        q = q + (np.swapaxes(jac, -1, -2) @ np.linalg.solve(jjt, err[..., None]))[..., 0]
    return q


def _ik_analytic(flange_pos: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All 8 analytic branches for a flange pose: (q (..., 8, 6), geometric validity (..., 8)).

    Branch b = 4 i1 + 2 i5 + i3 uses shoulder sign (+, -)[i1], wrist sign [i5], elbow sign [i3].
    """
    batch = flange_pos.shape[:-1]
    signs = np.array([[s1, s5, s3] for s1 in (1, -1) for s5 in (1, -1) for s3 in (1, -1)], float)
    s1, s5, s3 = (signs[:, k] for k in range(3))  # (8,)
    px, py = flange_pos[..., 0:1], flange_pos[..., 1:2]  # (..., 1)
    r = rot[..., None, :, :]  # (..., 1, 3, 3)

    # Shoulder: the wrist centre (frame 5 origin, d6 behind the flange along z6) sees the
    # shoulder through the d4 offset, which is perpendicular to the arm plane.
    wc = flange_pos - D6 * rot[..., :, 2]
    wc_r = np.hypot(wc[..., 0:1], wc[..., 1:2])
    arg1 = D4 / np.where(wc_r > 0.0, wc_r, np.inf)
    ok = np.broadcast_to(np.abs(arg1) <= 1.0, batch + (8,)).copy()
    q1 = np.arctan2(wc[..., 1:2], wc[..., 0:1]) + s1 * np.arccos(np.clip(arg1, -1, 1)) + np.pi / 2
    c1, sn1 = np.cos(q1), np.sin(q1)

    # Wrist 2: the flange position along the joint-1 normal is d4 + d6 cos(q5).
    arg5 = (px * sn1 - py * c1 - D4) / D6
    ok &= np.abs(arg5) <= 1.0 + 1e-9
    q5 = s5 * np.arccos(np.clip(arg5, -1, 1))
    sn5 = np.sin(q5)

    # Wrist 3 from the base x and y axes seen in the flange frame (rows of rot).
    num = -r[..., 0, 1] * sn1 + r[..., 1, 1] * c1
    den = r[..., 0, 0] * sn1 - r[..., 1, 0] * c1
    wrist_singular = np.abs(sn5) < 1e-10
    safe5 = np.where(wrist_singular, 1.0, sn5)
    q6 = np.where(wrist_singular, 0.0, np.arctan2(num / safe5, den / safe5))

    # Planar 3R chain (joints 2-4): frame 4 origin in frame 1.
    T06 = np.zeros(batch + (8, 4, 4))
    T06[..., :3, :3] = r
    T06[..., :3, 3] = flange_pos[..., None, :]
    T06[..., 3, 3] = 1.0
    T01 = _dh_transform(q1, 0)
    T45 = _dh_transform(q5, 4)
    T56 = _dh_transform(q6, 5)
    T14 = _rigid_inverse(T01) @ T06 @ _rigid_inverse(T45 @ T56)
    # Joints 2-4 are parallel to z1: frame 4's origin is (a2 c2 + a3 c23, a2 s2 + a3 s23) in the
    # x-y plane of frame 1 (its z is the d4 offset).
    x14, y14 = T14[..., 0, 3], T14[..., 1, 3]
    reach2 = x14**2 + y14**2
    arg3 = (reach2 - A2**2 - A3**2) / (2.0 * A2 * A3)
    ok &= np.abs(arg3) <= 1.0 + 1e-9
    q3 = s3 * np.arccos(np.clip(arg3, -1, 1))
    q2 = np.arctan2(y14, x14) - np.arctan2(A3 * np.sin(q3), A2 + A3 * np.cos(q3))
    T12 = _dh_transform(q2, 1)
    T23 = _dh_transform(q3, 2)
    T34 = _rigid_inverse(T12 @ T23) @ T14
    q4 = np.arctan2(T34[..., 1, 0], T34[..., 0, 0])
    q = np.stack([q1, q2, q3, q4, q5, q6], axis=-1)
    return q, ok & np.all(np.isfinite(q), axis=-1)


def ik_tcp(
    pos: np.ndarray, rot: np.ndarray, tool_length: float, refine_steps: int = 2
) -> tuple[np.ndarray, np.ndarray]:
    """All IK branches: pos (..., 3), rot (..., 3, 3) -> q (..., 8, 6), valid (..., 8).

    Joint angles are wrapped to (-pi, pi] and polished by `refine_steps` damped Newton steps.
    valid: the branch exists and fk_tcp(q) matches the target within IK_TOL_POS / IK_TOL_ROT.
    Invalid branches hold NaN.
    """
    pos = np.asarray(pos, dtype=np.float64)
    rot = np.asarray(rot, dtype=np.float64)
    if pos.shape[-1:] != (3,) or rot.shape[-2:] != (3, 3) or pos.shape[:-1] != rot.shape[:-2]:
        raise UsageError(
            f"ik_tcp needs pos (..., 3) and rot (..., 3, 3), got {pos.shape}, {rot.shape}"
        )
    flange = pos - tool_length * rot[..., :, 2]
    q, ok = _ik_analytic(flange, rot)
    q = np.where(ok[..., None], q, 0.0)
    pos8, rot8 = pos[..., None, :], rot[..., None, :, :]
    if refine_steps:
        q = refine_ik(q, pos8, rot8, tool_length, steps=refine_steps)
    q = wrap_angle(q)
    dp, dr = pose_error(q, pos8, rot8, tool_length)
    ok &= (dp < IK_TOL_POS) & (dr < IK_TOL_ROT)
    return np.where(ok[..., None], q, np.nan), ok


def closest_solution(
    solutions: np.ndarray, valid: np.ndarray, q_ref: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The valid branch nearest q_ref (wrapped distance): (..., 8, 6) -> q (..., 6), found (...,).

    q_ref defaults to HOME_Q. Where no branch is valid q is NaN and found is False.
    """
    q_ref = HOME_Q if q_ref is None else np.asarray(q_ref, dtype=np.float64)
    dist = np.linalg.norm(wrap_angle(solutions - q_ref[..., None, :]), axis=-1)
    dist = np.where(valid, dist, np.inf)
    best = np.argmin(dist, axis=-1)
    q = np.take_along_axis(solutions, best[..., None, None], axis=-2)[..., 0, :]
    found = np.any(valid, axis=-1)
    return np.where(found[..., None], q, np.nan), found


def ik_tcp_closest(
    pos: np.ndarray,
    rot: np.ndarray,
    tool_length: float,
    q_ref: np.ndarray | None = None,
    refine_steps: int = 2,
) -> tuple[np.ndarray, np.ndarray]:
    """The IK branch of a tcp pose nearest q_ref (default HOME_Q): q (..., 6), found (...,).

    The branch is chosen among the analytic solutions, then polished by `refine_steps` damped
    Newton steps and checked against IK_TOL_POS / IK_TOL_ROT.
    """
    pos = np.asarray(pos, dtype=np.float64)
    rot = np.asarray(rot, dtype=np.float64)
    solutions, valid = ik_tcp(pos, rot, tool_length, refine_steps=0)
    q, found = closest_solution(solutions, valid, q_ref)
    if refine_steps:
        q = refine_ik(np.where(found[..., None], q, 0.0), pos, rot, tool_length, refine_steps)
        q = wrap_angle(q)
        dp, dr = pose_error(q, pos, rot, tool_length)
        found &= (dp < IK_TOL_POS) & (dr < IK_TOL_ROT)
    return np.where(found[..., None], q, np.nan), found


@functools.lru_cache(maxsize=64)
def max_tool_down_radius(height: float, tool_length: float) -> float:
    """Largest horizontal distance (m) from the base axis at which the tcp, with the tool pointing
    down at `height` above the base, has an IK solution (bisection to 0.1 mm)."""
    rot = tool_down_rotation(0.0)

    def reachable(radius: float) -> bool:
        return bool(np.any(ik_tcp(np.array([radius, 0.0, height]), rot, tool_length)[1]))

    lo, hi = 0.3, 1.5
    if not reachable(lo):
        return 0.0
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if reachable(mid) else (lo, mid)
    return lo
