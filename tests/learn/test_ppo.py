"""learn/ppo.py: the policy starts at the baseline; its deterministic action is the exported
NumPy policy's."""

import jax.numpy as jnp
import numpy as np
import pytest

from mjx_peg.learn.ppo import deterministic_actions
from mjx_peg.learn.trainer import load_state
from mjx_peg.policy import observation
from mjx_peg.policy.export import load_policy
from mjx_peg.policy.network import controller_vector


def test_numpy_policy_equals_jax_deterministic_action(tiny_run):
    out, _ = tiny_run
    config, state = load_state(out)
    width = len(observation.LAYOUTS[config.observation])
    policy = load_policy(out)  # its part features held to its training parts' range
    obs = np.random.default_rng(0).normal(size=(1000, width)).astype(np.float32)
    obs = observation.clip_part(obs, *policy.part_range)
    jax_action = np.asarray(deterministic_actions(config, state, jnp.asarray(obs)))
    np_action = policy.act(obs)
    assert np.max(np.abs(np_action - jax_action)) < 1e-5


def test_prior_starts_at_the_baseline(tiny_config):
    config = tiny_config
    from mjx_peg.learn.ppo import init_state, make_networks
    from mjx_peg.skill.baseline import baseline_params

    obs = jnp.asarray(np.random.default_rng(1).normal(size=(64, 9)), jnp.float32)  # geometry
    base = baseline_params()
    for cfg in (config, config.replace(action_map="sigmoid")):
        state = init_state(cfg, make_networks(cfg))
        vec = controller_vector(deterministic_actions(cfg, state, obs), cfg.map_centre())
        vec = np.asarray(vec)
        np.testing.assert_allclose(vec[:, :2], np.broadcast_to(base[:2], (64, 2)), rtol=0.3)
        assert np.all(vec[:, 2] > 1.2e-3)  # lateral compliance near the baseline's 1.8e-3 m/N


def test_a_generic_start_is_the_mid_range_controller_for_every_observation():
    """--prior none: Brax's initialization, the mean head shrunk: every number mid-range (the
    sigmoid map's action 0) whatever the input, the search's constants too."""
    from mjx_peg.learn.config import PRESETS, prior_settings
    from mjx_peg.learn.ppo import init_state, make_networks
    from mjx_peg.skill.params import controller_from_action, vector_from_controller

    config = PRESETS["paper"].replace(**prior_settings("none"))
    assert config.action_size == 47 and config.map_centre() is None
    state = init_state(config, make_networks(config))
    width = len(observation.LAYOUTS[config.observation])
    obs = jnp.asarray(np.random.default_rng(5).normal(size=(64, width)), jnp.float32)
    action = np.asarray(deterministic_actions(config, state, obs))
    assert np.max(np.abs(action)) < 0.05
    middle = np.asarray(vector_from_controller(controller_from_action(np.zeros(47))))
    vectors = np.asarray(controller_vector(action, None))
    # |action| < 0.05 under the sigmoid map: k within 100^(0.05 / 4) = 1.059 of the middle
    np.testing.assert_allclose(vectors[:, :2], np.broadcast_to(middle[:2], (64, 2)), rtol=0.06)
    assert middle[0] == pytest.approx(100.0) and middle[38] == pytest.approx(0.005)


def test_the_learning_rate_follows_the_updates_kl(tiny_config):
    from mjx_peg.learn.ppo import adapt_learning_rate, learning_rate, make_optimizer

    config = tiny_config.replace(kl_target=0.01, learning_rate=1e-3)
    state = make_optimizer(config).init({"w": jnp.zeros(3)})
    rates = []
    for kl in (0.05, 0.05, 0.01, 0.001, 0.001):
        state = adapt_learning_rate(config, state, jnp.asarray(kl))
        rates.append(float(learning_rate(config, state)))
    np.testing.assert_allclose(rates, [1e-3 / 1.5, 1e-3 / 2.25, 1e-3 / 2.25, 1e-3 / 1.5, 1e-3],
                               rtol=1e-6)  # fmt: skip
    fixed = tiny_config.replace(kl_target=0.0)
    state = make_optimizer(fixed).init({"w": jnp.zeros(3)})
    assert adapt_learning_rate(fixed, state, jnp.asarray(1.0)) is state
    assert float(learning_rate(fixed, state)) == pytest.approx(fixed.learning_rate)


def test_the_exploration_std_decays_under_its_cap():
    """std_decay 0.25 over 32 iterations: every std at most 0.25 ** (k / 32) of its start after
    k iterations (0.5 halfway, 0.25 at the end); a std already under its cap is kept; std_decay
    1 leaves the params as they are."""
    from mjx_peg.learn.config import PRESETS, prior_settings
    from mjx_peg.learn.ppo import cap_exploration, init_state, make_networks

    config = PRESETS["paper"].replace(**prior_settings("none"), std_decay=0.25)
    assert config.iterations == 32
    params = init_state(config, make_networks(config)).params

    def stds(p):
        return np.exp(np.asarray(p.policy["params"]["std_logparam"]["log_value"]))

    np.testing.assert_allclose(stds(cap_exploration(config, params, 16)), 0.5, rtol=1e-6)
    np.testing.assert_allclose(stds(cap_exploration(config, params, 32)), 0.25, rtol=1e-6)
    low = params.policy["params"]["std_logparam"]["log_value"].at[3].set(np.log(0.1))
    policy = {**params.policy["params"], "std_logparam": {"log_value": low}}
    lowered = params.replace(policy={"params": policy})
    assert stds(cap_exploration(config, lowered, 16))[3] == pytest.approx(0.1)
    assert cap_exploration(config.replace(std_decay=1.0), params, 16) is params
