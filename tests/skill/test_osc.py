"""Task-frame state (finite differences), damped pseudo-inverse, OSC against C MuJoCo."""

import math

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mjx_peg.skill import dmp, osc
from mjx_peg.world.rotations import matrix_from_rotvec, rotvec_from_matrix, skew

H = 1e-6  # finite-difference step (s)
PINV_DAMPING = 0.01  # as in TrialConfig
TIMESTEP = 0.002
TORQUE_LIMITS = np.array([150.0, 150.0, 150.0, 28.0, 28.0, 28.0])

# A UR5e-like arm built from the DH table of CONVENTIONS.md: body i carries joint i (about its z)
# and sits at Tz(d) Tx(a) Rx(alpha) of link i - 1; masses close to the published ones.
_DH = [  # d, a, alpha, mass
    (0.1625, 0.0, math.pi / 2, 3.7),
    (0.0, -0.425, 0.0, 8.4),
    (0.0, -0.3922, 0.0, 2.3),
    (0.1333, 0.0, math.pi / 2, 1.2),
    (0.0997, 0.0, -math.pi / 2, 1.2),
    (0.0996, 0.0, 0.0, 0.4),
]
_NAMES = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]
PEG_LENGTH = 0.1


def _arm_xml() -> str:
    body_open, body_close = [], []
    pos, quat = (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0)
    for name, (d, a, alpha, mass) in zip(_NAMES, _DH, strict=True):
        com = (a / 2, 0.0, d / 2)
        inertia = mass * (d * d + a * a + 0.01) / 12.0
        body_open.append(
            f'<body name="{name}_link" pos="{pos[0]} {pos[1]} {pos[2]}" '
            f'quat="{quat[0]} {quat[1]} {quat[2]} {quat[3]}">'
            f'<joint name="{name}_joint" axis="0 0 1"/>'
            f'<inertial pos="{com[0]} {com[1]} {com[2]}" mass="{mass}" '
            f'diaginertia="{inertia} {inertia} {inertia / 2}"/>'
        )
        body_close.append("</body>")
        pos, quat = (a, 0.0, d), (math.cos(alpha / 2), math.sin(alpha / 2), 0.0, 0.0)
    tool = (
        f'<site name="flange" pos="0 0 {_DH[-1][0]}"/>'
        f'<site name="tcp" pos="0 0 {_DH[-1][0] + PEG_LENGTH}"/>'
        f'<body name="peg" pos="0 0 {_DH[-1][0]}"><inertial pos="0 0 0.05" mass="0.3" '
        f'diaginertia="3e-4 3e-4 1e-4"/></body>'
    )
    motors = "".join(
        f'<motor name="{n}" joint="{n}_joint" ctrlrange="{-lim} {lim}"/>'
        for n, lim in zip(_NAMES, TORQUE_LIMITS, strict=True)
    )
    return (
        '<mujoco model="arm"><compiler angle="radian"/>'
        '<option timestep="0.002" gravity="0 0 -9.81"/>'
        "<worldbody>" + "".join(body_open) + tool + "".join(reversed(body_close)) + "</worldbody>"
        "<actuator>" + motors + "</actuator></mujoco>"
    )


def _load_arm(kind):
    if kind == "test-arm":
        model = mujoco.MjModel.from_xml_string(_arm_xml())
    else:
        scene = pytest.importorskip("mjx_peg.world.scene")
        model = scene.load_model("square", 0.05)
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT  # free space
    assert model.opt.timestep == pytest.approx(TIMESTEP), "the controller runs at 500 Hz"
    return model


Q_START = np.array([0.3, -1.8, 1.9, -1.67, -1.57, 0.2])  # tool down, away from singularities


# ---------------------------------------------------------------- task state: finite differences


def _trajectory(t, rng_seed=0):
    """A smooth world-frame pose and its world velocities at time t (s)."""
    rng = np.random.default_rng(rng_seed)
    p0, v0, a0 = rng.normal(size=(3, 3)) * [[0.3], [0.2], [0.5]]
    r0 = Rotation.random(random_state=rng_seed).as_matrix()
    w0, alpha = rng.normal(size=(2, 3))
    pos = p0 + v0 * t + 0.5 * a0 * t * t
    vel = v0 + a0 * t
    # R(t) = exp([w0 t + alpha t^2 / 2]x) R0 is not a constant-axis motion; its world angular
    # velocity is J_l(phi) phi_dot with phi = w0 t + alpha t^2 / 2.
    phi = w0 * t + 0.5 * alpha * t * t
    phi_dot = w0 + alpha * t
    rot = matrix_from_rotvec(phi) @ r0
    return pos, rot, vel, _left_jacobian(phi) @ phi_dot


def _left_jacobian(phi):
    """(3, 3) J_l(phi): d/dt exp([phi]x) = [J_l(phi) phi_dot]x exp([phi]x)."""
    a = np.linalg.norm(phi)
    k = skew(phi)
    if a < 1e-8:
        return np.eye(3) + 0.5 * k
    return np.eye(3) + (1 - np.cos(a)) / a**2 * k + (a - np.sin(a)) / a**3 * (k @ k)


GOAL_POS = np.array([0.4, -0.2, 0.05])
GOAL_ROT = Rotation.from_rotvec([math.pi, 0.0, 0.3]).as_matrix()


def test_task_position_and_rotation_definitions():
    pos, rot, vel, omega = _trajectory(0.7)
    y, yd = osc.task_state(pos, rot, vel, omega, GOAL_POS, GOAL_ROT)
    np.testing.assert_allclose(y[:3], GOAL_ROT.T @ (pos - GOAL_POS), atol=1e-14)
    # theta = rotvec(R R_g^T), a world-frame rotation vector, expressed in the goal frame.
    theta_world = Rotation.from_matrix(rot @ GOAL_ROT.T).as_rotvec()
    np.testing.assert_allclose(y[3:], GOAL_ROT.T @ theta_world, atol=1e-12)
    np.testing.assert_allclose(yd, np.concatenate([GOAL_ROT.T @ vel, GOAL_ROT.T @ omega]))
    # At the goal the state is zero.
    y_goal, _ = osc.task_state(GOAL_POS, GOAL_ROT, vel, omega, GOAL_POS, GOAL_ROT)
    np.testing.assert_allclose(y_goal, 0.0, atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_task_velocity_matches_finite_differences(seed):
    """x_dot = yd[:3] exactly; theta_dot = J_l(theta)^-1 yd[3:] (yd holds angular velocity)."""
    t = 0.4
    y_plus, _ = osc.task_state(*_trajectory(t + H, seed), GOAL_POS, GOAL_ROT)
    y_minus, _ = osc.task_state(*_trajectory(t - H, seed), GOAL_POS, GOAL_ROT)
    y, yd = osc.task_state(*_trajectory(t, seed), GOAL_POS, GOAL_ROT)
    y_dot_fd = (y_plus - y_minus) / (2 * H)
    np.testing.assert_allclose(y_dot_fd[:3], yd[:3], atol=1e-7)
    np.testing.assert_allclose(_left_jacobian(y[3:]) @ y_dot_fd[3:], yd[3:], atol=1e-7)


def test_fixed_axis_rotation_velocity_is_theta_dot():
    """Straight-line rotations (the DMP's, in free space): yd[3:] is exactly d theta / dt."""
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])

    def pose(t):
        angle = 0.4 * math.sin(t)
        return GOAL_ROT @ matrix_from_rotvec(axis * angle), GOAL_ROT @ axis * 0.4 * math.cos(t)

    zero = np.zeros(3)
    t = 0.9
    (r_p, _), (r_m, _), (r, omega) = pose(t + H), pose(t - H), pose(t)
    th_p = osc.task_state(zero, r_p, zero, zero, zero, GOAL_ROT)[0][3:]
    th_m = osc.task_state(zero, r_m, zero, zero, zero, GOAL_ROT)[0][3:]
    _, yd = osc.task_state(zero, r, zero, omega, zero, GOAL_ROT)
    np.testing.assert_allclose((th_p - th_m) / (2 * H), yd[3:], atol=1e-8)


def test_world_from_task_accel_inverts_the_velocity_map():
    """d/dt of yd, mapped back to the world, is the world acceleration (finite differences)."""
    rng = np.random.default_rng(3)
    v0, acc, w0, alpha = rng.normal(size=(4, 3))
    zero = np.zeros(3)

    def yd_at(t):
        return osc.task_state(zero, np.eye(3), v0 + acc * t, w0 + alpha * t, zero, GOAL_ROT)[1]

    ydd_task = (yd_at(0.5 + H) - yd_at(0.5 - H)) / (2 * H)
    world = osc.world_from_task_accel(ydd_task, GOAL_ROT)
    np.testing.assert_allclose(world, np.concatenate([acc, alpha]), atol=1e-8)


# ----------------------------------------------------------------------- damped pseudo-inverse


def test_damped_pinv_is_pinv_without_damping_and_bounded_near_singularity():
    rng = np.random.default_rng(4)
    for n in (6, 7):
        jac = rng.normal(size=(5, 6, n))
        np.testing.assert_allclose(osc.damped_pinv(jac, 0.0), np.linalg.pinv(jac), atol=1e-9)
    u, _, vt = np.linalg.svd(rng.normal(size=(6, 6)))
    sigma = np.array([1.0, 0.5, 0.2, 0.1, 1e-3, 0.0])  # near and at a singularity
    jac = u @ np.diag(sigma) @ vt
    lam = 0.01
    pinv = osc.damped_pinv(jac, lam)
    expected = vt.T @ np.diag(sigma / (sigma**2 + lam**2)) @ u.T
    np.testing.assert_allclose(pinv, expected, atol=1e-9)
    assert np.linalg.norm(pinv, 2) <= 1.0 / (2 * lam) + 1e-9


def test_clamp_torque():
    u = np.array([[200.0, -200.0, 10.0, 30.0, -30.0, 0.0]])
    np.testing.assert_array_equal(osc.clamp_torque(u, TORQUE_LIMITS), [[150, -150, 10, 28, -28, 0]])


# ------------------------------------------------------------------------- OSC with C MuJoCo


def _kinematics(model, data, site):
    """tcp pos, rot, world velocity (6,), J (6, nv), Jd qd (6,), H, h of the current state."""
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jacp, jacr, site)
    jac = np.concatenate([jacp, jacr])
    dp, dr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    body = model.site_bodyid[site]
    mujoco.mj_jacDot(model, data, dp, dr, data.site_xpos[site], body)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    return (
        data.site_xpos[site].copy(),
        data.site_xmat[site].reshape(3, 3).copy(),
        jac @ data.qvel,
        jac,
        np.concatenate([dp, dr]) @ data.qvel,
        mass,
        # h of Eq. 12: Coriolis, centrifugal, gravity and the joints' passive (damping) torques.
        data.qfrc_bias - data.qfrc_passive,
    )


def _start(model, kind):
    data = mujoco.MjData(model)
    joints = [model.joint(f"{n}_joint").qposadr[0] for n in _NAMES]
    data.qpos[joints] = Q_START
    mujoco.mj_forward(model, data)
    return data, model.site("tcp").id


@pytest.mark.parametrize("kind", ["test-arm", "scene"])
def test_osc_realizes_the_commanded_acceleration(kind):
    """One step: J qdd + Jd qd equals the commanded task acceleration (small damping)."""
    model = _load_arm(kind)
    data, site = _start(model, kind)
    data.qvel[:6] = [0.2, -0.3, 0.4, 0.1, -0.2, 0.3]
    mujoco.mj_forward(model, data)
    _, _, _, jac, jdqd, mass, bias = _kinematics(model, data, site)
    ydd = np.array([0.5, -0.3, 1.0, 0.8, -0.4, 0.2])
    data.ctrl[:] = osc.osc_torque(mass, jac, jdqd, bias, ydd, 1e-6)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(jac @ data.qacc + jdqd, ydd, atol=1e-6)


@pytest.mark.parametrize("kind", ["test-arm", "scene"])
def test_osc_tracks_a_dmp_in_free_space(kind):
    """Gravity on, no contacts: the tcp follows the DMP's trajectory within 1 mm / 0.5 deg."""
    model = _load_arm(kind)
    data, site = _start(model, kind)
    config = dmp.DMPConfig()
    centers, widths = dmp.basis_centers(config.n_basis, config.phase_span)
    weights = dmp.fit_forcing_weights(config)
    start_pos = data.site_xpos[site].copy()
    start_rot = data.site_xmat[site].reshape(3, 3).copy()
    # Goal: 10 cm down, 5 cm sideways, turned by 10 deg about a tilted axis.
    goal_pos = start_pos + np.array([0.05, 0.0, -0.10])
    turn = np.radians(10.0) * np.array([0.6, 0.0, 0.8])
    goal_rot = matrix_from_rotvec(turn) @ start_rot
    zero = np.zeros(3)
    y0, _ = osc.task_state(start_pos, start_rot, zero, zero, goal_pos, goal_rot)
    k_y = dmp.stiffness_diag(100.0, 60.0)
    d_y = dmp.critical_damping(k_y, config.tau)
    duration = 4.0
    t_ref, y_ref, _ = dmp.rollout(
        y0, np.zeros(6), k_y, config, weights, duration=duration, dt=TIMESTEP
    )
    pos_err, ang_err = 0.0, 0.0
    for i, t in enumerate(t_ref):
        mujoco.mj_step1(model, data)
        pos, rot, vel, jac, jdqd, mass, bias = _kinematics(model, data, site)
        y, yd = osc.task_state(pos, rot, vel[:3], vel[3:], goal_pos, goal_rot)
        pos_err = max(pos_err, np.linalg.norm(y[:3] - y_ref[i, :3]))
        relative = matrix_from_rotvec(y[3:]) @ matrix_from_rotvec(y_ref[i, 3:]).T
        ang_err = max(ang_err, np.linalg.norm(rotvec_from_matrix(relative)))
        f = dmp.forcing(dmp.phase(t, config.tau, config.alpha_s), weights, centers, widths)
        g_m = dmp.scaled_modified_goal(np.zeros(6), y0, f, config.k_ref, np.zeros(6))
        ydd = dmp.dmp_acceleration(y, yd, g_m, k_y, d_y, config.tau)
        u = osc.osc_torque(
            mass, jac, jdqd, bias, osc.world_from_task_accel(ydd, goal_rot), PINV_DAMPING
        )
        data.ctrl[:] = osc.clamp_torque(u, TORQUE_LIMITS)
        mujoco.mj_step2(model, data)
    final = np.linalg.norm(y[:3])
    print(
        f"[{kind}] OSC tracking: max {1e3 * pos_err:.3f} mm, {np.degrees(ang_err):.4f} deg; "
        f"final {1e3 * final:.3f} mm from the goal"
    )
    assert pos_err < 1e-3 and np.degrees(ang_err) < 0.5
    assert final < 1e-3


def test_the_dead_band_shrinks_force_and_moment_by_their_widths():
    from mjx_peg.skill.control_step import deadband

    w = np.array([[3.0, 0.0, 4.0, 0.0, 0.3, 0.0], [1.0, 1.0, 1.0, 0.1, 0.1, 0.1]])
    out = deadband(w, 2.0, 0.4)
    np.testing.assert_allclose(out[0], [1.8, 0.0, 2.4, 0.0, 0.0, 0.0])  # |f| 5 -> 3, |m| < 0.4
    np.testing.assert_array_equal(out[1], 0.0)  # |f| = 1.73 N, |m| = 0.17 N m: the bias's size
    assert deadband(w, 0.0, 0.0) is w  # the paper's coupling: the wrench as it is
