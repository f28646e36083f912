"""The composed skill step: wrench referral, goal frame, torque at rest, NumPy == JAX."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mjx_peg.engines.trial import TrialConfig, control_config, fitted_basis
from mjx_peg.skill import control_step
from mjx_peg.skill.baseline import baseline_controller
from mjx_peg.skill.search import SkillConfig, skill_config
from mjx_peg.world.rotations import tool_down_rotation


def _random_rot(rng, n=None):
    return Rotation.random(n, random_state=rng).as_matrix()


def test_contact_force_at_tcp_gives_force_and_no_moment():
    """A pure force f on the peg at the tcp: the wrench at the tcp is (f, 0), in the goal frame."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        rot_ft, goal_rot = _random_rot(rng), _random_rot(rng)
        p_ft, p_tcp = rng.normal(size=3), rng.normal(size=3)
        f_contact = rng.normal(size=3) * 20
        tare = rng.normal(size=6)
        # Static peg: the flange's load on it changes by minus the contact wrench (about p_ft).
        load_f = -f_contact
        load_m = -np.cross(p_tcp - p_ft, f_contact)
        force_site = tare[:3] + rot_ft.T @ load_f
        torque_site = tare[3:] + rot_ft.T @ load_m
        w = control_step.wrench_in_goal_frame(
            force_site, torque_site, tare, rot_ft, p_ft - p_tcp, goal_rot
        )
        np.testing.assert_allclose(w[:3], goal_rot.T @ f_contact, atol=1e-12)
        np.testing.assert_allclose(w[3:], 0.0, atol=1e-12)


def test_tool_down_rotation_points_the_tool_down():
    yaw = np.array([0.0, 0.3, np.pi / 2])
    rot = tool_down_rotation(yaw)
    np.testing.assert_allclose(rot[:, :, 2], [[0, 0, -1]] * 3, atol=1e-15)
    np.testing.assert_allclose(rot[:, 0, 0], np.cos(yaw))
    np.testing.assert_allclose(np.linalg.det(rot), 1.0)


def _inputs(rng, batch, params):
    goal_rot = tool_down_rotation(rng.uniform(0, np.pi / 2, batch))
    goal_pos = rng.normal(size=(batch, 3))
    skill = control_step.make_skill(
        params, goal_pos, goal_rot, rng.normal(size=(batch, 6)) * 0.05, 1.0
    )
    jac = rng.normal(size=(batch, 6, 6)) + 3 * np.eye(6)
    a = rng.normal(size=(batch, 6, 6))
    mass = a @ np.swapaxes(a, 1, 2) + 6 * np.eye(6)
    args = dict(
        t=rng.uniform(0, 2, batch),
        tcp_pos=goal_pos + rng.normal(size=(batch, 3)) * 0.05,
        tcp_rot=None,  # set below: a rotation near goal_rot
        jac=jac,
        jdot_qdot=rng.normal(size=(batch, 6)),
        qvel=rng.normal(size=(batch, 6)) * 0.1,
        mass=mass,
        bias=rng.normal(size=(batch, 6)),
        wrench=rng.normal(size=(batch, 6)) * 10,
    )
    small = Rotation.from_rotvec(rng.normal(size=(batch, 3)) * 0.1).as_matrix()
    args["tcp_rot"] = small @ goal_rot
    return skill, args


def _torque(skill, basis, args, xp=np, trial=None):
    config = control_config(trial or TrialConfig(), xp)
    return control_step.skill_torque(config, skill, basis, control_step.Measurement(**args))


def test_at_rest_on_the_goal_the_torque_is_the_bias():
    """y = g = 0, yd = 0, F = 0, phase ended: no task acceleration, u = h (gravity etc.)."""
    rng = np.random.default_rng(1)
    skill, args = _inputs(rng, 4, baseline_controller())
    args.update(
        t=np.full(4, 50.0),
        tcp_pos=skill.goal_pos,
        tcp_rot=skill.goal_rot,
        qvel=np.zeros((4, 6)),
        jdot_qdot=np.zeros((4, 6)),
        wrench=np.zeros((4, 6)),
        bias=rng.uniform(-5, 5, (4, 6)),
    )
    u = _torque(skill, fitted_basis(TrialConfig().dmp), args)
    np.testing.assert_allclose(u, args["bias"], atol=1e-9)


# The skills, and the contact search's elements one by one: the centring alone, then the alignment.
SEARCHES = {
    "paper": SkillConfig(),
    "centring": SkillConfig(centre_gain=1.0),
    "alignment": SkillConfig(centre_gain=1.0, align_rate=1.0),
    "spiral": skill_config("spiral"),
}


@pytest.mark.parametrize("skill_name", list(SEARCHES))
def test_numpy_and_jax_agree(x64, skill_name):
    import jax
    import jax.numpy as jnp

    rng = np.random.default_rng(2)
    skill, args = _inputs(rng, 16, baseline_controller())
    trial = TrialConfig(search=SEARCHES[skill_name])
    if skill_name != "paper":  # half the rows pressed firmly enough to open the gate
        args["wrench"][::2, 2] = -rng.uniform(10.0, 40.0, 8)
    if skill_name in ("alignment", "spiral"):  # the goal turned by what the alignment found
        args["aligned"] = rng.normal(0.0, 0.1, (16, 3))
    if skill_name == "spiral":  # and moved along the spiral, its press lighter
        args["spiral"] = np.stack([rng.uniform(0.0, 20.0, 16), np.full(16, 0.08),
                                   rng.uniform(0.0, 1.0, 16)], axis=-1)  # fmt: skip
    basis = fitted_basis(TrialConfig().dmp)
    u_np = _torque(skill, basis, args, trial=trial)
    if skill_name == "centring":  # the pressed rows' goals moved (some torques are clamped)
        u_paper = _torque(skill, basis, args)
        assert (np.abs(u_np[::2] - u_paper[::2]).max(axis=1) > 1e-3).sum() >= 4
        np.testing.assert_array_equal(u_np[1::2], u_paper[1::2])
    to_j = lambda tree: jax.tree.map(jnp.asarray, tree)  # noqa: E731
    fn = jax.jit(lambda s, b, a: _torque(s, b, a, jnp, trial))
    u_jax = np.asarray(fn(to_j(skill), to_j(basis), to_j(args)))
    np.testing.assert_allclose(u_jax, u_np, rtol=1e-9, atol=1e-9)
    assert np.all(np.abs(u_np) <= np.array([150, 150, 150, 28, 28, 28]) + 1e-12)
