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
runs it unbatched in NumPy. Like dmp.py and osc.py it imports neither numpy nor jax.
"""

from __future__ import annotations

from typing import NamedTuple

from mjx_peg.skill import dmp, osc
from mjx_peg.skill.params import ControllerParams


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
    return osc.task_state(
        tcp_pos, tcp_rot, tcp_vel[..., :3], tcp_vel[..., 3:], skill.goal_pos, skill.goal_rot
    )


class Measurement(NamedTuple):
    """What one control period measures (a pytree under JAX); leading dims are trials."""

    t: object  # (...,) s since the start of the movement
    tcp_pos: object  # (..., 3) tcp position, world frame
    tcp_rot: object  # (..., 3, 3) tcp orientation, world frame
    jac: object  # (..., 6, n) tcp Jacobian (linear rows, then angular), world frame
    jdot_qdot: object  # (..., 6) Jd qd of the tcp, world frame
    qvel: object  # (..., n) joint velocities
    mass: object  # (..., n, n) joint-space inertia H
    bias: object  # (..., n) h: Coriolis, centrifugal and gravity torques
    wrench: object  # (..., 6) external wrench at the tcp, goal frame (`wrench_in_goal_frame`)


class ControlConfig(NamedTuple):
    """Constants of the control step shared by every trial of a batch."""

    tau: float  # s, DMP time constant
    alpha_s: float  # phase decay
    k_ref: float  # 1/s^2, stiffness the forcing term was fitted at (dmp.scaled_modified_goal)
    pinv_damping: float  # damping of J+ near singularities
    torque_limits: object  # (n,) N m, symmetric joint torque limits


def skill_torque(config: ControlConfig, skill: Skill, basis: Basis, meas: Measurement):
    """(..., n) joint torques of the compliant DMP for one control period (Eqs. 2, 6, 10-14)."""
    tcp_vel = (meas.jac @ meas.qvel[..., None])[..., 0]
    y, yd = task_state(skill, meas.tcp_pos, meas.tcp_rot, tcp_vel)
    s = dmp.phase(meas.t, config.tau, config.alpha_s)
    f = dmp.forcing(s, basis.weights, basis.centers, basis.widths)
    dy = dmp.compliance_offset(skill.compliance, meas.wrench)
    goal = 0.0 * skill.y0  # the goal is the origin of the goal frame
    g_m = dmp.scaled_modified_goal(goal, skill.y0, f, config.k_ref, dy)
    ydd_task = dmp.dmp_acceleration(y, yd, g_m, skill.k_y, skill.d_y, config.tau)
    ydd_world = osc.world_from_task_accel(ydd_task, skill.goal_rot)
    u = osc.osc_torque(
        meas.mass, meas.jac, meas.jdot_qdot, meas.bias, ydd_world, config.pinv_damping
    )
    return osc.clamp_torque(u, config.torque_limits)


def start_state(skill_goal_pos, skill_goal_rot, tcp_pos, tcp_rot):
    """(..., 6) y at the start of a trial (the DMP's y0), from the measured tcp pose."""
    xp = tcp_pos.__array_namespace__()
    zero = xp.zeros_like(tcp_pos)
    y, _ = osc.task_state(tcp_pos, tcp_rot, zero, zero, skill_goal_pos, skill_goal_rot)
    return y


__all__ = [
    "Basis",
    "ControlConfig",
    "Measurement",
    "Skill",
    "make_skill",
    "skill_torque",
    "start_state",
    "task_state",
    "wrench_in_goal_frame",
]
