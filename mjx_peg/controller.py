"""The compliant-DMP skill as one control step: measured arm state -> joint torques.

This composes the paper's pieces (sections 3-4) into the controller that runs at 500 Hz:

    y, yd   = task state of the tcp in the goal frame                (CONVENTIONS.md)
    F       = tared external wrench on the peg, in the goal frame
    s       = exp(-alpha_s t / tau)                                    (phase, Eq. 2)
    dy      = C F,  C = K_c^-1                                         (Eq. 6)
    g_m     = g + k_ref^-1 (g - y0) f(s) + dy,  g = 0 in the goal frame
              (Eq. 11 with f scaled by K_y / k_ref, see dmp.scaled_modified_goal)
    ydd     = tau^-1 (K_y (g_m - y) - D_y yd)                          (Eq. 10)
    u       = H J+ (ydd - Jd qd) + h,  clamped to the torque limits    (Eq. 14)

Written once over the array-API namespace of its inputs, batched over leading dimensions: the
MJX engine jits and vmaps it, the C MuJoCo engine runs it batched in NumPy, and the robot runtime
runs it unbatched in NumPy. Like dmp.py and control.py it imports neither numpy nor jax.
"""

from __future__ import annotations

from typing import NamedTuple

from mjx_peg import control, dmp
from mjx_peg.params import ControllerParams


class Skill(NamedTuple):
    """Per-trial constants of the skill (a pytree under JAX)."""

    goal_pos: object  # (..., 3) goal position of the tcp, world frame
    goal_rot: object  # (..., 3, 3) goal orientation of the tcp, world frame
    y0: object  # (..., 6) start of the movement in the goal frame
    k_y: object  # (..., 6) diagonal of K_y
    d_y: object  # (..., 6) diagonal of D_y (critical damping)
    compliance: object  # (..., 6, 6) C = K_c^-1


class Basis(NamedTuple):
    """The fitted forcing term (not learned): weights and Gaussian basis of the phase."""

    weights: object  # (n_basis,)
    centers: object  # (n_basis,)
    widths: object  # (n_basis,)


def goal_rotation(yaw):
    """(..., 3, 3) tool-down orientation whose x axis is at `yaw` about world z.

    R = Rz(yaw) Rx(pi): the tool z axis points along world -z.
    """
    xp = yaw.__array_namespace__()
    c, s = xp.cos(yaw), xp.sin(yaw)
    z, o = xp.zeros_like(yaw), xp.ones_like(yaw)
    rows = [
        xp.stack([c, s, z], axis=-1),
        xp.stack([s, -c, z], axis=-1),
        xp.stack([z, z, -o], axis=-1),
    ]
    return xp.stack(rows, axis=-2)


def make_skill(params: ControllerParams, goal_pos, goal_rot, y0, tau: float) -> Skill:
    """Skill constants from the learned parameters and the goal; D_y for critical damping."""
    k_y = dmp.stiffness_diag(params.k_t, params.k_theta)
    return Skill(goal_pos, goal_rot, y0, k_y, dmp.critical_damping(k_y, tau), params.compliance)


def wrench_in_goal_frame(force_site, torque_site, tare, rot_site, lever_world, goal_rot):
    """(..., 6) external wrench on the peg at the tcp, in the goal frame, from a tared F/T reading.

    force_site, torque_site: (..., 3) sensor reading in the sensor site frame (MuJoCo reports the
    load the flange exerts on the peg, so the contact wrench is minus its change since the tare);
    tare: (..., 6) the reading at rest at the start; rot_site: (..., 3, 3) sensor orientation;
    lever_world: (..., 3) p_sensor - p_tcp, world frame. The moment is referred to the tcp, the
    point the DMP controls: m_tcp = m_sensor + (p_sensor - p_tcp) x f. Referred to the sensor,
    150 mm above the tip, every lateral tip force would become a moment that tilts the peg.
    """
    xp = force_site.__array_namespace__()
    f_world = (rot_site @ (tare[..., :3] - force_site)[..., None])[..., 0]
    m_world = (rot_site @ (tare[..., 3:] - torque_site)[..., None])[..., 0]
    m_world = m_world + xp.linalg.cross(lever_world, f_world)
    to_goal = xp.matrix_transpose(goal_rot)
    f_goal = (to_goal @ f_world[..., None])[..., 0]
    m_goal = (to_goal @ m_world[..., None])[..., 0]
    return xp.concat([f_goal, m_goal], axis=-1)


def task_state(skill: Skill, tcp_pos, tcp_rot, tcp_vel):
    """y, yd (..., 6) of the tcp in the goal frame; tcp_vel (..., 6) = [linear, angular], world."""
    return control.task_state(
        tcp_pos, tcp_rot, tcp_vel[..., :3], tcp_vel[..., 3:], skill.goal_pos, skill.goal_rot
    )


def skill_torque(
    skill: Skill,
    basis: Basis,
    t,
    tcp_pos,
    tcp_rot,
    jac,
    jdot_qdot,
    qvel,
    mass,
    bias,
    wrench_goal,
    torque_limits,
    tau: float,
    alpha_s: float,
    k_ref: float,
    pinv_damping: float,
):
    """(..., n) joint torques of the compliant DMP at time t (s) since the start of the movement.

    jac: (..., 6, n) tcp Jacobian (linear rows, then angular), world frame; jdot_qdot: (..., 6);
    qvel: (..., n); mass: (..., n, n) joint-space inertia H; bias: (..., n) h (Coriolis, gravity);
    wrench_goal: (..., 6) from `wrench_in_goal_frame`.
    """
    tcp_vel = (jac @ qvel[..., None])[..., 0]
    y, yd = task_state(skill, tcp_pos, tcp_rot, tcp_vel)
    s = dmp.phase(t, tau, alpha_s)
    f = dmp.forcing(s, basis.weights, basis.centers, basis.widths)
    dy = dmp.compliance_offset(skill.compliance, wrench_goal)
    goal = 0.0 * skill.y0  # the goal is the origin of the goal frame
    g_m = dmp.scaled_modified_goal(goal, skill.y0, f, k_ref, dy)
    ydd_task = dmp.dmp_acceleration(y, yd, g_m, skill.k_y, skill.d_y, tau)
    ydd_world = control.world_from_task_accel(ydd_task, skill.goal_rot)
    u = control.osc_torque(mass, jac, jdot_qdot, bias, ydd_world, pinv_damping)
    return control.clamp_torque(u, torque_limits)


def start_state(skill_goal_pos, skill_goal_rot, tcp_pos, tcp_rot):
    """(..., 6) y at the start of a trial (the DMP's y0), from the measured tcp pose."""
    xp = tcp_pos.__array_namespace__()
    zero = xp.zeros_like(tcp_pos)
    y, _ = control.task_state(tcp_pos, tcp_rot, zero, zero, skill_goal_pos, skill_goal_rot)
    return y


__all__ = [
    "Basis",
    "Skill",
    "goal_rotation",
    "make_skill",
    "skill_torque",
    "start_state",
    "task_state",
    "wrench_in_goal_frame",
]
