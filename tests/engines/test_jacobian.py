"""engines/jacobian.py: the tcp Jacobian and its derivative, and the mass matrix, to the bit."""

import numpy as np


def test_jacobians_and_mass_match_mujoco():
    """`jacobians` is mj_jacSite and mj_jacDot, the dense mass matrix mj_fullM, to the bit."""
    import mujoco

    from mjx_peg.engines.jacobian import dense_mass_index, jacobians
    from mjx_peg.world import scene

    m = scene.load_model("circle", 0.05)
    ids = scene.scene_ids(m)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    index = dense_mass_index(m)
    for _ in range(20):
        d.qpos[:] = rng.uniform(-np.pi, np.pi, 6)
        d.qvel[:] = rng.normal(size=6)
        mujoco.mj_step1(m, d)
        jl, ja, dl, da = (np.zeros((3, 6)) for _ in range(4))
        mujoco.mj_jacSite(m, d, jl, ja, ids.tcp_site)
        mujoco.mj_jacDot(m, d, dl, da, d.site_xpos[ids.tcp_site], ids.wrist3_body)
        root = m.body_rootid[ids.wrist3_body]
        jac, jac_dot = jacobians(
            d.cdof[None], d.cdof_dot[None], d.cvel[ids.wrist3_body][None],
            d.subtree_com[root][None], d.site_xpos[ids.tcp_site][None],
        )  # fmt: skip
        np.testing.assert_array_equal(jac[0], np.concatenate([jl, ja]))
        np.testing.assert_array_equal(jac_dot[0], np.concatenate([dl, da]))
        mass = np.zeros((6, 6))
        mujoco.mj_fullM(m, d, mass)
        np.testing.assert_array_equal(d.M[index].reshape(6, 6), mass)
