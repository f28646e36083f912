"""The compliant-DMP skill as one control step: measured arm state -> joint torques.

This composes the paper's pieces (sections 3-4) into the controller that runs at 500 Hz:

    y, yd   = task state of the tcp in the goal frame                (CONVENTIONS.md)
    F       = the sensed external wrench on the peg, goal frame, at the tcp (skill/sensor.py)
    W       = F through the compliance damping: W_k = a_c W_(k-1) + (1 - a_c) F_k
    s       = exp(-alpha_s t / tau)                                    (phase, Eq. 2)
    dy      = C W,  C = K_c^-1                                         (Eqs. 4, 6)
    g_m     = g + k_ref^-1 (g - y0) f(s) + dy,  g = 0 in the goal frame
              (Eq. 11 with f scaled by K_y / k_ref, see dmp.scaled_modified_goal)
    ydd     = tau^-1 (K_y (g_m - y) - D_y yd)                          (Eq. 10)
    u       = H J+ (ydd - Jd qd) + h,  clamped to the torque limits    (Eq. 14)

Change to the paper's literal form: the compliance keeps its damping. The paper writes the
compliance as F = K_c dy + D_c dy_dot (Eq. 4) and drops D_c. We keep D_c = T_c K_c with a fixed
time constant T_c (`TrialConfig.coupling_time_constant`, 0.75 s): then C F = dy + T_c dy_dot,
i.e. dy = C W with W a first-order low-pass of the sensed wrench (a_c = exp(-T / T_c)), derived
below. The 38 learned numbers (k_t, k_theta, the full C) are the paper's; T_c is not learned.

Why the loop needs it (stability of the coupling through the contact). In a rigid contact the
tcp cannot move along the constrained directions, so the operational-space command becomes
contact force at once: F = -Lambda ydd (Lambda = (J H^-1 J^T)^-1, the inertia a force at the
tcp meets), and with yd = 0, F_k = c - Lambda K_y C W_k / tau. The wrench the compliance sees
is the physics' last step (one period old), d further periods late (the sensor's latency),
low-passed by the sensor's filter (pole a_s) and by the damping (a_c). Per eigenvalue L of the
loop gain C Lambda K_y / tau the loop closes as

    z^(d-1) (z - a_s)(z - a_c) + L (1 - a_s)(1 - a_c) = 0     (times z when d = 0)

and is stable iff every root lies inside the unit circle (`coupling_loop_radius`,
`max_stable_loop_gain`):
- without filters or latency the root is z = -L: the force alternates every 2 ms step (250 Hz)
  and grows once L > 1;
- the UR5e sensor alone (50 Hz filter, one period of latency) moves the limit to L = 2.1 only;
- a damping pole a_c lifts it to about (T_c / T) c(d), c = 2 (d = 0, no sensor filter), 1.0
  (d = 1), 0.56-0.62 (d = 2), 0.40-0.45 (d = 3): the loop then acts as an integrator behind a
  delay, and its force still settles within about T_c / L in a rigid contact.
T_c is chosen so that every learnable vector (k_t, k_theta up to 1000, the compliance within its
bounds, over Lambda across the workspace) stays stable for the nominal sensor and the whole
training randomization (latency 0-2 periods, filters of 25-100 Hz); the loop gains, the limits
and the measurements behind T_c: docs/design/compliance_damping.md.

Written once over the array-API namespace of its inputs, batched over leading dimensions: the
MJX engine jits and vmaps it, the C MuJoCo engine runs it batched in NumPy, and the robot runtime
runs it unbatched in NumPy. Like dmp.py and osc.py it imports neither numpy nor jax (the
stability helpers at the end import NumPy when called).
"""

from __future__ import annotations

import importlib
import math
from typing import NamedTuple

from mjx_peg.array_api import matvec
from mjx_peg.skill import dmp, osc
from mjx_peg.skill.params import ControllerParams
from mjx_peg.skill.search import SearchValues, SkillConfig, bounded_press, searched_offset


class SkillConsts(NamedTuple):
    """Per-trial constants of the skill (a pytree under JAX)."""

    goal_pos: object  # (..., 3) goal position of the tcp, world frame
    goal_rot: object  # (..., 3, 3) goal orientation of the tcp, world frame
    y0: object  # (..., 6) start of the movement in the goal frame
    k_y: object  # (..., 6) diagonal of K_y
    d_y: object  # (..., 6) diagonal of D_y (critical damping)
    compliance: object  # (..., 6, 6) C = K_c^-1
    # the contact search's learned constants of each trial (`search.SearchValues`, (...,) each);
    # None: the skill config's
    search: SearchValues | None = None


class Basis(NamedTuple):
    """The fitted forcing term (not learned): weights and Gaussian basis of the phase."""

    weights: object  # (n_basis,)
    centers: object  # (n_basis,)
    widths: object  # (n_basis,)


def make_skill(params: ControllerParams, goal_pos, goal_rot, y0, tau: float,
               search: SearchValues | None = None) -> SkillConsts:  # fmt: skip
    """Per-trial constants from the learned parameters and the goal; D_y for critical damping;
    search: the contact search's learned constants (None: the skill config's)."""
    k_y = dmp.stiffness_diag(params.k_t, params.k_theta)
    return SkillConsts(
        goal_pos, goal_rot, y0, k_y, dmp.critical_damping(k_y, tau), params.compliance, search
    )


def external_wrench(force_site, torque_site, tare):
    """(..., 6) tared external wrench on the peg in the sensor frame, from an F/T reading.

    force_site, torque_site: (..., 3) reading in the sensor site frame; MuJoCo (and the arm)
    report the load the flange exerts on the peg, so the contact wrench is minus its change since
    the tare (..., 6), the reading at rest at the start.
    """
    xp = force_site.__array_namespace__()
    return xp.concat([tare[..., :3] - force_site, tare[..., 3:] - torque_site], axis=-1)


def wrench_to_goal(wrench_site, rot_site, lever_world, goal_rot):
    """(..., 6) a sensor-frame wrench (..., 6) at the tcp, in the goal frame.

    rot_site: (..., 3, 3) sensor orientation; lever_world: (..., 3) p_sensor - p_tcp, world frame.
    The moment is referred to the tcp, the point the DMP controls: m_tcp = m_sensor +
    (p_sensor - p_tcp) x f. Referred to the sensor, 150 mm above the tip, every lateral tip force
    would become a moment that tilts the peg.
    """
    xp = wrench_site.__array_namespace__()
    f_world = matvec(rot_site, wrench_site[..., :3])
    m_world = matvec(rot_site, wrench_site[..., 3:])
    m_world = m_world + xp.linalg.cross(lever_world, f_world)
    to_goal = xp.matrix_transpose(goal_rot)
    f_goal = matvec(to_goal, f_world)
    m_goal = matvec(to_goal, m_world)
    return xp.concat([f_goal, m_goal], axis=-1)


def wrench_in_goal_frame(force_site, torque_site, tare, rot_site, lever_world, goal_rot):
    """(..., 6) external wrench on the peg at the tcp, in the goal frame, from a tared F/T reading
    (`external_wrench` then `wrench_to_goal`, without the sensor pipeline)."""
    return wrench_to_goal(
        external_wrench(force_site, torque_site, tare), rot_site, lever_world, goal_rot
    )


def task_state(skill: SkillConsts, tcp_pos, tcp_rot, tcp_vel):
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
    # (..., 6) the sensed external wrench at the tcp, goal frame, after the F/T pipeline
    # (skill/sensor.py) and the compliance damping's low-pass (module docstring)
    wrench: object
    # (..., 3) the goal's rotation the contact search's alignment has found
    # (`search.aligned_rotation`, carried by the caller); None: none
    aligned: object = None
    # (..., 3) the contact search's spiral state (`search.spiral_state`, carried by the caller);
    # None: none
    spiral: object = None


class ControlConfig(NamedTuple):
    """Constants of the control step shared by every trial of a batch."""

    tau: float  # s, DMP time constant
    alpha_s: float  # phase decay
    k_ref: float  # 1/s^2, stiffness the forcing term was fitted at (dmp.scaled_modified_goal)
    pinv_damping: float  # damping of J+ near singularities
    torque_limits: object  # (n,) N m, symmetric joint torque limits
    # N and N m: the compliance ignores this much of the wrench's force and moment (`deadband`);
    # 0: the paper's literal coupling
    force_deadband: float = 0.0
    moment_deadband: float = 0.0
    # the contact search (skill/search.py); the default, all off: the paper's skill
    search: SkillConfig = SkillConfig()
    # s: the duration T of the movement the forcing term was fitted to (`dmp.DMPConfig`); a
    # trial whose learned duration differs runs the fitted movement's phase at T / T_trial
    movement_s: float = 2.0


def _shrink(v, width: float):
    """v (..., 3) moved towards 0 by `width` in norm, 0 within it: v max(0, 1 - width / |v|)."""
    xp = v.__array_namespace__()
    norm = xp.linalg.vector_norm(v, axis=-1, keepdims=True)
    return v * xp.maximum(1.0 - width / xp.maximum(norm, 1e-12), 0.0)


def deadband(wrench, force: float, moment: float):
    """(..., 6) the wrench the compliance acts on: its force and its moment each shrunk by a
    dead band of radius `force` (N) and `moment` (N m); zero width leaves it as it is.

    An extension of the paper's coupling (README, changes): what a tared F/T sensor reports in
    free motion (a residual bias of up to 1 N and 0.1 N m per axis, the peg's inertia) would
    otherwise move the goal by C F, several mm at the baseline's 1.8e-3 m/N, before any contact.
    """
    if force == 0.0 and moment == 0.0:
        return wrench
    xp = wrench.__array_namespace__()
    return xp.concat([_shrink(wrench[..., :3], force), _shrink(wrench[..., 3:], moment)], axis=-1)


def skill_torque(config: ControlConfig, skill: SkillConsts, basis: Basis, meas: Measurement):
    """(..., n) joint torques of the compliant DMP for one control period (Eqs. 2, 6, 10-14),
    with the contact search of `config.search` where it is on (skill/search.py)."""
    tcp_vel = matvec(meas.jac, meas.qvel)
    y, yd = task_state(skill, meas.tcp_pos, meas.tcp_rot, tcp_vel)
    t = meas.t
    if skill.search is not None and skill.search.movement_s is not None:
        # the fitted movement played at the trial's duration
        t = t * (config.movement_s / skill.search.movement_s)
    s = dmp.phase(t, config.tau, config.alpha_s)
    f = dmp.forcing(s, basis.weights, basis.centers, basis.widths)
    wrench = deadband(meas.wrench, config.force_deadband, config.moment_deadband)
    dy = dmp.compliance_offset(skill.compliance, wrench)
    if config.search.active:
        height = -y[..., 2]  # the tcp over the goal (goal z points down, into the hole)
        dy = searched_offset(
            config.search, dy, wrench, meas.aligned, meas.spiral, height, skill.search
        )
    goal = 0.0 * skill.y0  # the goal is the origin of the goal frame
    g_m = dmp.scaled_modified_goal(goal, skill.y0, f, config.k_ref, dy)
    ydd_task = dmp.dmp_acceleration(y, yd, g_m, skill.k_y, skill.d_y, config.tau)
    if config.search.press_accel > 0:
        ydd_task = bounded_press(config.search, ydd_task)
    ydd_world = osc.world_from_task_accel(ydd_task, skill.goal_rot)
    u = osc.osc_torque(
        meas.mass, meas.jac, meas.jdot_qdot, meas.bias, ydd_world, config.pinv_damping
    )
    return osc.clamp_torque(u, config.torque_limits)


# -- stability of the compliance loop (NumPy analysis, module docstring) ---------------------------


def coupling_loop_radius(loop_gain, sensor_pole: float, coupling_pole: float, delay: int) -> float:
    """Largest |z| of z^(d-1) (z - a_s)(z - a_c) + L (1 - a_s)(1 - a_c) = 0 (times z for d = 0):
    the compliance loop closed through a rigid contact, per eigenvalue L (complex allowed) of
    C Lambda K_y / tau; a_s the sensor filter's pole, a_c the compliance damping's, d the
    sensor's latency in control periods (on top of the physics' one step). Below 1: stable."""
    np = importlib.import_module("numpy")
    a_s, a_c, d = float(sensor_pole), float(coupling_pole), int(delay)
    extra = max(0, 1 - d)
    poly = np.polymul(np.polymul([1.0, -a_s], [1.0, -a_c]), np.r_[1.0, np.zeros(d - 1 + extra)])
    poly = poly.astype(complex)
    poly[len(poly) - 1 - extra] += complex(loop_gain) * (1.0 - a_s) * (1.0 - a_c)
    return float(np.abs(np.roots(poly)).max())


def max_stable_loop_gain(
    sensor_pole: float, coupling_pole: float, delay: int, radius: float = 1.0
) -> float:
    """The largest real loop gain L whose loop keeps every pole inside `radius` (bisection)."""
    lo, hi = 0.0, 1.0
    while coupling_loop_radius(hi, sensor_pole, coupling_pole, delay) < radius:
        lo, hi = hi, 2.0 * hi
        if hi > 1e9:
            return math.inf
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if coupling_loop_radius(mid, sensor_pole, coupling_pole, delay) < radius:
            lo = mid
        else:
            hi = mid
    return lo


def coupling_time_constant_for(
    loop_gain: float, sensor_pole: float, delay: int, timestep: float, radius: float = 1.0
) -> float:
    """The shortest compliance-damping time constant T_c (s) that keeps a loop of gain
    `loop_gain` stable (every pole inside `radius`) behind the given sensor (bisection)."""

    def stable(tc):
        a_c = math.exp(-timestep / tc)
        return coupling_loop_radius(loop_gain, sensor_pole, a_c, delay) < radius

    if coupling_loop_radius(loop_gain, sensor_pole, 0.0, delay) < radius:
        return 0.0
    lo, hi = timestep, 2.0 * timestep
    while not stable(hi):
        lo, hi = hi, 2.0 * hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if stable(mid) else (mid, hi)
    return hi


def contact_loop_gain(compliance, k_y, task_inertia, tau: float = 1.0) -> float:
    """max |eig(C Lambda K_y / tau)| (NumPy): the compliance loop's gain through a rigid
    contact; compliance (6, 6), k_y (6,), task_inertia Lambda (6, 6) in the goal frame."""
    np = importlib.import_module("numpy")
    c, lam = np.asarray(compliance, float), np.asarray(task_inertia, float)
    return float(np.abs(np.linalg.eigvals(c @ lam * (np.asarray(k_y, float) / tau))).max())


def task_inertia(mass, jac, goal_rot):
    """(6, 6) Lambda = (J H^-1 J^T)^-1 of the tcp in the goal frame (NumPy): the inertia a
    contact force at the tcp meets; mass H (n, n), jac (6, n) world frame, goal_rot (3, 3)."""
    np = importlib.import_module("numpy")
    j = np.asarray(jac, float)
    lam_world = np.linalg.inv(j @ np.linalg.solve(np.asarray(mass, float), j.T))
    r = np.zeros((6, 6))
    r[:3, :3] = r[3:, 3:] = np.asarray(goal_rot, float)
    return r.T @ lam_world @ r


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
    "SkillConsts",
    "contact_loop_gain",
    "coupling_loop_radius",
    "coupling_time_constant_for",
    "max_stable_loop_gain",
    "task_inertia",
    "make_skill",
    "skill_torque",
    "start_state",
    "task_state",
    "external_wrench",
    "wrench_in_goal_frame",
    "wrench_to_goal",
]
