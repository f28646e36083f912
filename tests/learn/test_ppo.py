"""learn/ppo.py: the policy starts at the baseline; its deterministic action is the exported
NumPy policy's."""

import jax.numpy as jnp
import numpy as np

from mjx_peg.learn.ppo import deterministic_actions
from mjx_peg.learn.trainer import load_state
from mjx_peg.policy import observation
from mjx_peg.policy.export import load_policy
from mjx_peg.policy.network import controller_vector


def test_numpy_policy_equals_jax_deterministic_action(tiny_run):
    out, _ = tiny_run
    config, state = load_state(out)
    obs = np.random.default_rng(0).normal(size=(1000, observation.OBS_SIZE)).astype(np.float32)
    jax_action = np.asarray(deterministic_actions(config, state, jnp.asarray(obs)))
    np_action = load_policy(out).act(obs)
    assert np.max(np.abs(np_action - jax_action)) < 1e-5


def test_prior_starts_at_the_baseline(tiny_config):
    config = tiny_config
    from mjx_peg.learn.ppo import init_state, make_networks
    from mjx_peg.skill.baseline import baseline_params

    obs = jnp.asarray(np.random.default_rng(1).normal(size=(64, 8)), jnp.float32)
    base = baseline_params()
    for cfg in (config, config.replace(action_map="sigmoid")):
        state = init_state(cfg, make_networks(cfg))
        vec = controller_vector(deterministic_actions(cfg, state, obs), cfg.map_centre())
        vec = np.asarray(vec)
        np.testing.assert_allclose(vec[:, :2], np.broadcast_to(base[:2], (64, 2)), rtol=0.3)
        assert np.all(vec[:, 2] > 1.2e-3)  # lateral compliance near the baseline's 1.8e-3 m/N
