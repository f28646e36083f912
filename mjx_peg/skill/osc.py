"""Operational-space torque control of the tcp (paper section 4.1) and the task-frame state.

    dynamics     H(q) qdd + h(q, qd) = u                                              (Eq. 12)
    task space   H* ydd + h* = u,  H* = H J+,  h* = h - H J+ Jd qd                     (Eq. 13)
    control      u = H* tau^-1 (K_y (g_m - y) - D_y yd) + h*                          (Eq. 14)

J is the tcp Jacobian in the world frame (linear rows, then angular), J+ a damped
pseudo-inverse. The task state y = [x, theta] is the tcp pose in the goal (task) frame,
CONVENTIONS.md "Controller task frame".

Written once over the array-API namespace of the inputs, batched over leading dimensions; this
module imports neither numpy nor jax.
"""

from __future__ import annotations

from mjx_peg.array_api import matmul, matvec, namespace_of, solve_spd
from mjx_peg.world.rotations import rotvec_from_matrix


def _transpose(mat):
    """(..., n, m) transpose of the last two axes of mat (..., m, n)."""
    xp = namespace_of(mat)
    return xp.matrix_transpose(mat)


def task_state(pos_world, rot_world, vel_lin_world, vel_ang_world, goal_pos_world, goal_rot_world):
    """y, yd (..., 6) of a frame (pos (..., 3), rot (..., 3, 3), velocities (..., 3)), goal frame.

    x = R_g^T (p - p_g); theta = rotvec(R R_g^T) expressed in the goal frame = rotvec(R_g^T R);
    xd = R_g^T v; the angular part of yd is the angular velocity in the goal frame, R_g^T omega.
    That equals d theta / dt when the rotation axis is fixed (the DMP's straight-line rotations
    in free space) and to first order in |theta| otherwise (dtheta/dt = J_l(theta)^-1 R_g^T omega,
    J_l^-1 = I - [theta]x / 2 + O(|theta|^2)); the controller works with angular velocity and
    acceleration, as the paper's yd = J qd.
    """
    xp = namespace_of(pos_world, rot_world, goal_pos_world, goal_rot_world)
    rot_goal_t = _transpose(goal_rot_world)
    x = matvec(rot_goal_t, pos_world - goal_pos_world)
    theta = rotvec_from_matrix(matmul(rot_goal_t, rot_world))
    xd = matvec(rot_goal_t, vel_lin_world)
    omega = matvec(rot_goal_t, vel_ang_world)
    return xp.concat([x, theta], axis=-1), xp.concat([xd, omega], axis=-1)


def world_from_task_accel(ydd_task, goal_rot_world):
    """(..., 6) [linear, angular] tcp acceleration in the world frame from ydd_task (..., 6).

    The inverse of `task_state`'s velocity map, differentiated with the goal frame fixed:
    pdd = R_g xdd, omegad = R_g (d/dt of the angular part of yd).
    """
    xp = namespace_of(ydd_task, goal_rot_world)
    lin = matvec(goal_rot_world, ydd_task[..., :3])
    ang = matvec(goal_rot_world, ydd_task[..., 3:])
    return xp.concat([lin, ang], axis=-1)


def damped_gram(jac, damping):
    """(..., 6, 6) J J^T + lambda^2 I of jac (..., 6, n): the matrix `damped_pinv` inverts."""
    xp = namespace_of(jac)
    m = jac.shape[-2]
    return matmul(jac, _transpose(jac)) + (damping**2) * xp.eye(m, dtype=jac.dtype)


def damped_pinv(jac, damping):
    """(..., n, 6) damped pseudo-inverse J+ = J^T (J J^T + lambda^2 I)^-1 of jac (..., 6, n).

    Each singular value sigma of J is inverted as sigma / (sigma^2 + lambda^2) instead of
    1 / sigma: far from singularities (sigma >> lambda) this is the pseudo-inverse up to a
    relative error (lambda / sigma)^2; near one (sigma -> 0) the gain along the lost direction
    peaks at 1 / (2 lambda) at sigma = lambda and then goes to zero, so joint accelerations and
    torques stay bounded, at the price of not realizing the commanded task acceleration along
    that direction. lambda has the units of J (m per rad for the linear rows, 1 for the angular
    ones); 0.01 is small next to the UR5e's singular values (about 0.1 to 1.5) away from its
    singular poses.
    """
    xp = namespace_of(jac)
    # J^T (J J^T + l^2 I)^-1 = ((J J^T + l^2 I)^-1 J)^T since the Gram matrix is symmetric.
    return _transpose(xp.linalg.solve(damped_gram(jac, damping), jac))


def osc_torque(mass_matrix, jac, jdot_qdot, bias, ydd_des, damping):
    """(..., n) u = H J+ (ydd_des - Jd qd) + h (Eqs. 13, 14).

    mass_matrix H (..., n, n); jac J (..., 6, n) world frame, [linear; angular]; jdot_qdot Jd qd
    (..., 6); bias h (..., n) (Coriolis, centrifugal, gravity); ydd_des (..., 6) desired
    [linear, angular] tcp acceleration in the world frame, e.g. `world_from_task_accel` of
    `dmp.dmp_acceleration`; damping lambda of `damped_pinv`.
    """
    gram = damped_gram(jac, damping)
    # qdd = J+ (ydd - Jd qd) with one solve instead of an explicit inverse.
    qdd = matvec(_transpose(jac), solve_spd(gram, ydd_des - jdot_qdot))
    return matvec(mass_matrix, qdd) + bias


def clamp_torque(u, limits):
    """(..., n) u clipped to [-limits, limits]; limits (n,) or (..., n), positive (N m)."""
    xp = namespace_of(u, limits)
    limits = xp.asarray(limits, dtype=u.dtype)
    return xp.minimum(xp.maximum(u, -limits), limits)


__all__ = [
    "clamp_torque",
    "damped_gram",
    "damped_pinv",
    "osc_torque",
    "task_state",
    "world_from_task_accel",
]
