"""UR5e kinematics: FK against independent chains and the MJCF, Jacobian against finite
differences, analytic IK round trips on every branch."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mjx_peg.world import constants
from mjx_peg.world import kinematics as kin
from mjx_peg.world.rotations import matrix_from_rotvec, rotvec_from_matrix, tool_down_rotation

TOOL = 0.12  # m, any tool length works for the pure-kinematics tests
IK_TOL = 1e-6  # m and rad, the brief's round-trip tolerance


def _random_q(seed: int, n: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-np.pi, np.pi, (n, 6))


def _elementary_chain(q: np.ndarray) -> np.ndarray:
    """Flange transform from explicit Rz Tz Tx Rx factors (scipy rotations), one q (6,)."""

    def rot(axis, angle):
        out = np.eye(4)
        out[:3, :3] = Rotation.from_euler(axis, angle).as_matrix()
        return out

    def trans(axis, dist):
        out = np.eye(4)
        out["xyz".index(axis), 3] = dist
        return out

    T = np.eye(4)
    for i in range(6):
        T = T @ rot("z", q[i]) @ trans("z", kin.DH_D[i]) @ trans("x", kin.DH_A[i])
        T = T @ rot("x", kin.DH_ALPHA[i])
    return T


def _rot_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.norm(rotvec_from_matrix(a @ np.swapaxes(b, -1, -2)), axis=-1)


def test_fk_zero_pose_is_urs_published_one():
    """At q = 0 tool0 sits at (a2 + a3, -(d4 + d6), d1 - d5) = (-817.2, -232.9, 62.8) mm."""
    pos, rot = kin.fk_flange(np.zeros(6))
    np.testing.assert_allclose(pos, [-0.8172, -0.2329, 0.0628], atol=1e-12)
    np.testing.assert_allclose(rot, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-12)  # Rx(pi/2)


def test_fk_matches_elementary_transforms_batched():
    q = _random_q(0, 50).reshape(5, 10, 6)
    pos, rot = kin.fk_flange(q)
    assert pos.shape == (5, 10, 3) and rot.shape == (5, 10, 3, 3)
    for idx in np.ndindex(5, 10):
        T = _elementary_chain(q[idx])
        np.testing.assert_allclose(pos[idx], T[:3, 3], atol=1e-12)
        np.testing.assert_allclose(rot[idx], T[:3, :3], atol=1e-12)
    tcp, tcp_rot = kin.fk_tcp(q, TOOL)
    np.testing.assert_allclose(tcp, pos + TOOL * rot[..., :, 2], atol=1e-15)
    np.testing.assert_array_equal(tcp_rot, rot)


def test_home_points_the_tool_down_in_front_of_the_robot():
    pos, rot = kin.fk_tcp(kin.HOME_Q, TOOL)
    np.testing.assert_allclose(rot[:, 2], [0, 0, -1], atol=1e-12)
    assert pos[0] > 0.4 and abs(pos[1]) < 0.2


def test_fk_tcp_matches_the_mujoco_model():
    """The MJCF's `flange` and `tcp` sites equal DH tool0 and fk_tcp(q, PEG_LENGTH) at 50 q."""
    import mujoco

    from mjx_peg.world import scene

    model = scene.load_model("square", 0.05)
    data = mujoco.MjData(model)
    adr = [model.jnt_qposadr[model.joint(name).id] for name in constants.JOINT_NAMES]
    flange, tcp = model.site("flange").id, model.site("tcp").id
    q = _random_q(1, 50)
    pos_flange, rot_flange = kin.fk_flange(q)
    pos_tcp, _ = kin.fk_tcp(q, constants.PEG_LENGTH)
    for i in range(len(q)):
        data.qpos[adr] = q[i]
        mujoco.mj_kinematics(model, data)
        for site, pos in ((flange, pos_flange[i]), (tcp, pos_tcp[i])):
            assert np.linalg.norm(data.site_xpos[site] - pos) < 1e-6
            assert _rot_angle(data.site_xmat[site].reshape(3, 3), rot_flange[i]) < 1e-6


def test_tcp_kinematics_matches_mujocos_jacobian_and_its_derivative():
    """tcp_kinematics (one pass over the DH frames) gives fk_tcp, jacobian_tcp and dJ/dt equal
    to MuJoCo's mj_jacSite / mj_jacDot of the `tcp` site at 20 random q, qd (1e-12)."""
    import mujoco

    from mjx_peg.world import scene

    model = scene.load_model("circle", 0.05)
    data = mujoco.MjData(model)
    ids = scene.scene_ids(model)
    q, qd = _random_q(3, 20), np.random.default_rng(4).uniform(-2.0, 2.0, (20, 6))
    pos, rot, jac, jac_dot = kin.tcp_kinematics(q, qd, constants.PEG_LENGTH)
    np.testing.assert_array_equal(pos, kin.fk_tcp(q, constants.PEG_LENGTH)[0])
    np.testing.assert_allclose(jac, kin.jacobian_tcp(q, constants.PEG_LENGTH), atol=1e-15)
    lin, ang = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for i in range(len(q)):
        data.qpos[ids.qpos_adr], data.qvel[ids.dof_adr] = q[i], qd[i]
        mujoco.mj_forward(model, data)
        mujoco.mj_jacSite(model, data, lin, ang, ids.tcp_site)
        np.testing.assert_allclose(np.concatenate([lin, ang])[:, ids.dof_adr], jac[i], atol=1e-12)
        mujoco.mj_jacDot(model, data, lin, ang, data.site_xpos[ids.tcp_site], ids.wrist3_body)
        expected = np.concatenate([lin, ang])[:, ids.dof_adr]
        assert np.abs(expected).max() > 0.1  # qd moves the Jacobian: the check can fail
        np.testing.assert_allclose(kin.jacobian_dot_tcp(q[i], qd[i], constants.PEG_LENGTH),
                                   expected, atol=1e-12)  # fmt: skip


def test_jacobian_matches_finite_differences():
    h = 1e-6
    q = _random_q(2, 20)
    jac = kin.jacobian_tcp(q, TOOL)
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = h
        p_plus, r_plus = kin.fk_tcp(q + dq, TOOL)
        p_minus, r_minus = kin.fk_tcp(q - dq, TOOL)
        lin = (p_plus - p_minus) / (2 * h)
        ang = rotvec_from_matrix(r_plus @ np.swapaxes(r_minus, -1, -2)) / (2 * h)
        np.testing.assert_allclose(jac[:, :3, j], lin, atol=1e-5)
        np.testing.assert_allclose(jac[:, 3:, j], ang, atol=1e-5)


def test_ik_every_branch_reproduces_1000_random_poses():
    q_true = _random_q(3, 1000)
    pos, rot = kin.fk_tcp(q_true, TOOL)
    solutions, valid = kin.ik_tcp(pos, rot, TOOL)
    assert solutions.shape == (1000, 8, 6) and valid.shape == (1000, 8)
    # Independent check of every returned branch.
    p, r = kin.fk_tcp(np.where(valid[..., None], solutions, 0.0), TOOL)
    pos_err = np.linalg.norm(p - pos[:, None], axis=-1)[valid]
    rot_err = _rot_angle(r, rot[:, None])[valid]
    print(
        f"IK: max error {pos_err.max():.2e} m, {rot_err.max():.2e} rad; "
        f"{valid.mean():.3f} of branches exist"
    )
    assert pos_err.max() < IK_TOL and rot_err.max() < IK_TOL
    assert np.all(np.abs(solutions[valid]) <= np.pi)
    assert np.all(np.isnan(solutions[~valid]))
    # The configuration the pose came from is one of the branches.
    dist = np.linalg.norm(kin.wrap_angle(solutions - q_true[:, None]), axis=-1)
    assert np.nanmin(dist, axis=1).max() < 1e-8
    # A random pose of the arm has 8 distinct solutions unless an acos argument leaves [-1, 1]
    # (then 4 or 2); branches come in such groups.
    counts = valid.sum(axis=1)
    assert set(np.unique(counts)) <= {2, 4, 6, 8} and (counts == 8).mean() > 0.7
    full = solutions[counts == 8]
    pair = np.linalg.norm(kin.wrap_angle(full[:, :, None] - full[:, None, :]), axis=-1)
    assert np.all(pair[:, ~np.eye(8, dtype=bool)] > 1e-6)


def test_analytic_ik_is_exact_without_newton_steps():
    q_true = _random_q(4, 1000)
    pos, rot = kin.fk_tcp(q_true, TOOL)
    solutions, valid = kin.ik_tcp(pos, rot, TOOL, refine_steps=0)
    p, r = kin.fk_tcp(np.where(valid[..., None], solutions, 0.0), TOOL)
    assert np.linalg.norm(p - pos[:, None], axis=-1)[valid].max() < 1e-9
    assert _rot_angle(r, rot[:, None])[valid].max() < 1e-9


def test_ik_closest_picks_home_branch_and_is_exact():
    pos, rot = kin.fk_tcp(kin.HOME_Q, TOOL)
    q, found = kin.ik_tcp_closest(pos, rot, TOOL)
    assert found
    np.testing.assert_allclose(kin.wrap_angle(q - kin.HOME_Q), 0.0, atol=1e-9)
    # Tool-down poses over the workspace: elbow up, wrist down, error < 1e-9 after polishing.
    rng = np.random.default_rng(5)
    radius, angle = rng.uniform(0.35, 0.65, 500), rng.uniform(-np.pi / 3, np.pi / 3, 500)
    pos = np.stack([radius * np.cos(angle), radius * np.sin(angle), rng.uniform(0, 0.2, 500)], -1)
    rot = tool_down_rotation(rng.uniform(-0.5, 2.0, 500))
    q, found = kin.ik_tcp_closest(pos, rot, TOOL)
    assert found.all()
    pos_err, rot_err = kin.pose_error(q, pos, rot, TOOL)
    assert pos_err.max() < 1e-9 and rot_err.max() < 1e-9
    assert np.all(q[:, 2] > 0) and np.all(q[:, 4] < 0)  # elbow up, wrist down
    assert np.all(np.abs(q) <= np.pi)


def test_ik_out_of_reach_finds_nothing():
    q, found = kin.ik_tcp_closest(np.array([1.5, 0.0, 0.1]), tool_down_rotation(0.0), TOOL)
    assert not found and np.all(np.isnan(q))
    _, valid = kin.ik_tcp(np.array([0.0, 0.0, 0.3]), tool_down_rotation(0.0), TOOL)
    assert not valid.any()  # on the base axis: inside the d4 offset cylinder


def test_condition_number_flags_singularities():
    good = kin.condition_number(kin.HOME_Q, TOOL)
    assert 1.0 < good < 20.0
    wrist = kin.HOME_Q.copy()
    wrist[4] = 0.0  # z4 and z6 aligned
    elbow = kin.HOME_Q.copy()
    elbow[2] = 0.0  # arm stretched
    assert kin.condition_number(wrist, TOOL) > 1e8
    assert kin.condition_number(elbow, TOOL) > 1e8
    # The wrist joints move the offset tcp, so the 3x6 position block stays well conditioned at
    # both: it is no singularity measure, and the sampler bounds the full Jacobian.
    assert kin.condition_number(elbow, TOOL, "position") < 20.0
    assert kin.condition_number(wrist, TOOL, "position") < 20.0
    with pytest.raises(ValueError, match="unknown block"):
        kin.condition_number(kin.HOME_Q, TOOL, "angular")


def test_rotation_helpers_round_trip():
    rng = np.random.default_rng(6)
    rotvec = Rotation.random(200, random_state=7).as_rotvec()
    rotvec[:5] *= (np.pi - 1e-7) / np.linalg.norm(rotvec[:5], axis=-1, keepdims=True)
    rotvec[5] = 0.0
    rot = matrix_from_rotvec(rotvec)
    np.testing.assert_allclose(rot, Rotation.from_rotvec(rotvec).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(rotvec_from_matrix(rot), rotvec, atol=1e-6)
    yaw = rng.uniform(-np.pi, np.pi, 10)
    expected = Rotation.from_euler("ZX", np.stack([yaw, np.full(10, np.pi)], -1)).as_matrix()
    np.testing.assert_allclose(tool_down_rotation(yaw), expected, atol=1e-12)
    assert np.all(kin.wrap_angle(np.array([np.pi, -np.pi, 3 * np.pi])) == np.pi)


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match=r"\(\.\.\., 6\)"):
        kin.fk_flange(np.zeros(5))
    with pytest.raises(ValueError, match="ik_tcp needs"):
        kin.ik_tcp(np.zeros(2), np.eye(3), TOOL)
