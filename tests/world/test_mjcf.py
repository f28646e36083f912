"""world/mjcf.py: the scene it builds: the UR5e against its DH figures, compiled in MuJoCo and
MJX, the hole's clearance, a peg through the hole, the F/T sensor, bad input."""

import math

import mujoco
import numpy as np
import pytest

from mjx_peg.world import constants, mjcf, pose_solver, scene
from mjx_peg.world.rotations import tool_down_rotation

SIZES_MM = (25, 37, 50, 60)
ALL_SCENES = [(shape, mm) for shape in constants.SHAPES for mm in SIZES_MM]


# --- independent DH forward kinematics (written here on purpose, not imported) ------------------
DH = [  # (d, a, alpha)
    (0.1625, 0.0, math.pi / 2),
    (0.0, -0.425, 0.0),
    (0.0, -0.3922, 0.0),
    (0.1333, 0.0, math.pi / 2),
    (0.0997, 0.0, -math.pi / 2),
    (0.0996, 0.0, 0.0),
]


def dh_tool0(q):
    """4x4 pose of DH frame 6 (tool0) in the base frame: prod Rz(q) Tz(d) Tx(a) Rx(alpha)."""
    T = np.eye(4)
    for qi, (d, a, alpha) in zip(q, DH, strict=True):
        rz = np.array(
            [
                [math.cos(qi), -math.sin(qi), 0, 0],
                [math.sin(qi), math.cos(qi), 0, 0],
                [0, 0, 1, 0],
                [0, 0, 0, 1],
            ]
        )
        tz = np.eye(4)
        tz[2, 3] = d
        tx = np.eye(4)
        tx[0, 3] = a
        ca, sa = math.cos(alpha), math.sin(alpha)
        rx = np.array([[1, 0, 0, 0], [0, ca, -sa, 0], [0, sa, ca, 0], [0, 0, 0, 1]])
        T = T @ rz @ tz @ tx @ rx
    return T


def rot_angle(r1, r2):
    """Angle (rad) of r1 r2^T, accurate for tiny angles."""
    d = r1 @ r2.T
    s = 0.5 * np.linalg.norm([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]])
    c = 0.5 * (np.trace(d) - 1.0)
    return math.atan2(s, c)


def place_tool_down(model, tcp_pos, yaw):
    """MjData with the arm's tcp at `tcp_pos`, tool pointing down at `yaw` (mj_forward done)."""
    ids = scene.scene_ids(model)
    q = pose_solver.solve_site_pose(model, tcp_pos, tool_down_rotation(yaw))
    data = mujoco.MjData(model)
    data.qpos[ids.qpos_adr] = q
    mujoco.mj_forward(model, data)
    assert np.linalg.norm(data.site_xpos[ids.tcp_site] - tcp_pos) < 1e-9
    assert rot_angle(data.site_xmat[ids.tcp_site].reshape(3, 3), tool_down_rotation(yaw)) < 1e-9
    return data


def board_contacts(model, data):
    board = set(scene.board_geom_ids(model).tolist())
    return [
        i
        for i in range(data.ncon)
        if data.contact.geom1[i] in board or data.contact.geom2[i] in board
    ]


def rot_z(a):
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def test_flange_site_equals_dh_tool0_at_random_q():
    model = scene.load_model("square", 0.05)
    data = mujoco.MjData(model)
    ids = scene.scene_ids(model)
    rng = np.random.default_rng(0)
    pos_err, rot_err = 0.0, 0.0
    for q in rng.uniform(-2 * np.pi, 2 * np.pi, size=(50, 6)):
        data.qpos[ids.qpos_adr] = q
        mujoco.mj_kinematics(model, data)
        T = dh_tool0(q)
        pos_err = max(pos_err, np.linalg.norm(data.site_xpos[ids.flange_site] - T[:3, 3]))
        rot_err = max(rot_err, rot_angle(data.site_xmat[ids.flange_site].reshape(3, 3), T[:3, :3]))
        # tcp: PEG_LENGTH along the flange z, same orientation.
        tcp = T[:3, 3] + constants.PEG_LENGTH * T[:3, 2]
        assert np.linalg.norm(data.site_xpos[ids.tcp_site] - tcp) < 1e-6
    assert pos_err < 1e-6 and rot_err < 1e-6, (pos_err, rot_err)


def test_arm_dynamics_parameters():
    model = scene.load_model("circle", 0.05)
    names = [
        "shoulder_link",
        "upper_arm_link",
        "forearm_link",
        "wrist_1_link",
        "wrist_2_link",
        "wrist_3_link",
    ]
    masses = [model.body(n).mass[0] for n in names]
    np.testing.assert_allclose(masses, [3.761, 8.058, 2.846, 1.37, 1.3, 0.365])
    assert model.body("peg").mass[0] == pytest.approx(constants.PEG_MASS)
    assert model.nq == model.nv == model.nu == 6
    ids = scene.scene_ids(model)
    np.testing.assert_array_equal(ids.dof_adr, np.arange(6))
    np.testing.assert_allclose(
        model.actuator_ctrlrange[ids.actuator_ids, 1], constants.TORQUE_LIMITS
    )
    np.testing.assert_allclose(
        model.actuator_forcerange[ids.actuator_ids, 0], -np.array(constants.TORQUE_LIMITS)
    )
    np.testing.assert_allclose(model.jnt_range[ids.joint_ids], [[-2 * np.pi, 2 * np.pi]] * 6)
    assert np.all(model.dof_armature[ids.dof_adr] > 0) and np.all(
        model.dof_damping[ids.dof_adr] > 0
    )
    assert model.opt.timestep == 0.002
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL


@pytest.mark.parametrize(("shape", "mm"), ALL_SCENES)
def test_scene_compiles_in_mujoco_and_mjx(shape, mm):
    from mujoco import mjx

    model = scene.load_model(shape, mm / 1000)
    assert model.nv == 6
    # Only peg-board and peg-table contacts: every other geom has contype = conaffinity = 0.
    peg, board = scene.peg_geom_ids(model), scene.board_geom_ids(model)
    table = model.geom("table").id
    assert len(peg) == 1 and len(board) == constants.HOLE_SIDES[shape]
    others = np.setdiff1d(np.arange(model.ngeom), np.concatenate([peg, board, [table]]))
    assert np.all(model.geom_contype[others] == 0) and np.all(model.geom_conaffinity[others] == 0)
    assert np.all(model.geom_condim[np.concatenate([peg, board, [table]])] == 3)
    for g in board.tolist() + [table]:  # filter: peg-board yes, board-table no
        assert (
            model.geom_contype[peg[0]] & model.geom_conaffinity[g]
            or model.geom_contype[g] & model.geom_conaffinity[peg[0]]
        )
    assert not (model.geom_contype[board[0]] & model.geom_conaffinity[table])
    mx = mjx.put_model(model)
    assert mx.nv == 6


@pytest.mark.slow
def test_one_mjx_step_matches_mujoco():
    """One MJX step of the circle's scene (its peg a convex mesh prism) in free space is
    MuJoCo's; the square's scene runs MJX end to end in tests/engines/test_mjx.py."""
    from mujoco import mjx

    from mjx_peg.engines.mjx import jit

    model = scene.load_model("circle", 0.05)
    data = place_tool_down(model, (0.45, 0.1, 0.3), 0.2)
    data.ctrl[:] = data.qfrc_bias[:6] + np.array([5.0, -5.0, 3.0, 1.0, -1.0, 0.5])
    mx = mjx.put_model(model)
    dx = mjx.put_data(model, data)
    dx = jit(mjx.step)(mx, dx)
    mujoco.mj_step(model, data)
    qpos, qvel = np.asarray(dx.qpos), np.asarray(dx.qvel)
    assert np.all(np.isfinite(qpos)) and np.all(np.isfinite(qvel))
    np.testing.assert_allclose(qpos, data.qpos, atol=1e-5)
    np.testing.assert_allclose(qvel, data.qvel, atol=2e-3 * np.abs(data.qvel).max() + 1e-4)


@pytest.mark.parametrize(("shape", "mm"), ALL_SCENES)
def test_peg_passes_the_hole_straight_and_hits_with_3mm_offset(shape, mm):
    """Zero errors: the peg slides down the hole axis to 20 mm above the table, touching nothing."""
    size = mm / 1000
    model = scene.load_model(shape, size)
    yaw = 0.4
    data = place_tool_down(model, (0.5, -0.05, 0.35), yaw)
    ids = scene.scene_ids(model)
    tip = data.site_xpos[ids.tip_site].copy()
    rot = tool_down_rotation(yaw)
    board = ids.board_body

    def probe(h, offset_board=(0.0, 0.0)):
        """Board contacts with the tip h above the board-frame table, the hole offset laterally."""
        off = rot_z(yaw) @ np.array([*offset_board, 0.0])
        model.body_pos[board] = tip - np.array([0, 0, h]) + off
        model.body_quat[board] = (math.cos(yaw / 2), 0, 0, math.sin(yaw / 2))
        mujoco.mj_forward(model, data)
        return board_contacts(model, data)

    assert rot_angle(data.site_xmat[ids.tip_site].reshape(3, 3), rot) < 1e-9
    for h in np.arange(0.16, 0.0199, -0.005):
        assert probe(h) == [], f"contact at tip height {h:.3f}"
    for off in ((0.003, 0), (-0.003, 0), (0, 0.003), (0, -0.003)):
        assert probe(0.02, off), f"no contact with offset {off}"
        assert probe(0.2, off) == []  # above the board: still free


def _ft(model, data, ids):
    rot = data.site_xmat[ids.ft_site].reshape(3, 3)
    f = data.sensordata[ids.ft_force_adr : ids.ft_force_adr + 3].copy()
    t = data.sensordata[ids.ft_torque_adr : ids.ft_torque_adr + 3].copy()
    return f, t, rot


KP = np.array([800.0, 800.0, 400.0, 60.0, 60.0, 40.0])  # N m / rad


KD = np.array([40.0, 40.0, 20.0, 3.0, 3.0, 2.0])  # N m s / rad (explicit: kd dt / M_ii << 1)


def _step(model, data, ids, q_ref=None, kp=KP, kd=KD):
    """One step with exact gravity/Coriolis compensation (+ joint PD to q_ref when given)."""
    mujoco.mj_step1(model, data)
    u = data.qfrc_bias[ids.dof_adr].copy()
    qv = data.qvel[ids.dof_adr]
    if q_ref is not None:
        u += kp * (q_ref - data.qpos[ids.qpos_adr]) - kd * qv
    else:
        u -= 0.1 * kd * qv
    data.ctrl[ids.actuator_ids] = u
    mujoco.mj_step2(model, data)


@pytest.mark.parametrize("shape", constants.SHAPES)
def test_ft_sensor_tared_free_space_and_known_push(shape):
    size = 0.05
    model = scene.load_model(shape, size)
    ids = scene.scene_ids(model)
    scene.set_board_pose(model, 0.45, 0.0, 0.0)
    yaw, spot = 0.0, np.array([0.45 + 0.065, 0.0])  # a solid part of the board top
    top = constants.HOLE_DEPTH
    q_high = pose_solver.solve_site_pose(model, (*spot, top + 0.05), tool_down_rotation(yaw))
    q_low = pose_solver.solve_site_pose(
        model, (*spot, top + 0.003), tool_down_rotation(yaw), q_init=q_high
    )
    data = mujoco.MjData(model)
    data.qpos[ids.qpos_adr] = q_high
    mujoco.mj_forward(model, data)
    for _ in range(100):  # 0.2 s still, then tare
        _step(model, data, ids, q_high)
    tare_f, tare_t, _ = _ft(model, data, ids)
    assert np.linalg.norm(tare_f) == pytest.approx(constants.PEG_MASS * 9.81, rel=1e-3)
    # Free space: a 1 s minimum-jerk joint move down to 3 mm above the board, then 0.2 s still.
    free = []
    n = 500
    for k in range(n + 100):
        s = min(1.0, (k + 1) / n)
        q_ref = q_high + (q_low - q_high) * (10 * s**3 - 15 * s**4 + 6 * s**5)
        _step(model, data, ids, q_ref)
        f, t, _ = _ft(model, data, ids)
        free.append(np.linalg.norm(f - tare_f))
    assert data.ncon == 0
    assert max(free) < 0.5, max(free)
    # Push: the arm only gravity-compensated and damped, a known force down on the wrist-3 body.
    push = 40.0
    data.xfrc_applied[ids.wrist3_body] = [0, 0, -push, 0, 0, 0]
    for _ in range(1000):  # 2 s
        _step(model, data, ids)
    assert np.abs(data.qvel).max() < 1e-3
    assert board_contacts(model, data)
    f, t, rot = _ft(model, data, ids)
    measured = rot @ (f - tare_f)  # world frame: the wrench of the wrist-3 body on the peg
    np.testing.assert_allclose(measured, [0, 0, -push], atol=0.05 * push)
    assert abs(measured[2] + push) < 0.05 * push


@pytest.mark.parametrize(
    ("shape", "size"),
    [
        ("octagon", 0.05),
        ("Circle", 0.05),
        ("square", 0.0),
        ("square", -0.01),
        ("circle", float("nan")),
        ("triangle", float("inf")),
    ],
)
def test_bad_input_raises_one_line_value_error(shape, size):
    for fn in (mjcf.build_mjcf, scene.load_model):
        with pytest.raises(ValueError) as err:
            fn(shape, size)
        msg = str(err.value)
        assert "\n" not in msg and msg
        assert ("circle, square, triangle" in msg) if "shape" in msg else ("> 0" in msg)
