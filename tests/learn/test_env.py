"""learn/env.py: one environment step is one trial of the engine."""

import jax
import jax.numpy as jnp
import numpy as np
from brax.envs.wrappers.training import VmapWrapper

from mjx_peg.engines import run_trials
from mjx_peg.learn.config import TrainConfig
from mjx_peg.learn.env import InsertionEnv, specs_from_seeds
from mjx_peg.policy import observation
from mjx_peg.policy.network import controller_vector


def test_env_reset_and_step_are_one_trial():
    config = TrainConfig(time_limit_s=1.0)
    centre = config.map_centre()
    assert config.observation == "geometry"  # new runs read parts by their geometry
    env = VmapWrapper(
        InsertionEnv(
            config.task(), config.trial(), action_centre=centre, action_size=config.action_size
        )
    )
    state = jax.jit(env.reset)(jax.random.split(jax.random.PRNGKey(1), 4))
    specs = specs_from_seeds(config.task(), np.asarray(state.info["seed"]))
    policy_obs = observation.observe_specs(specs, "geometry")
    np.testing.assert_allclose(state.obs["state"], policy_obs, atol=1e-6)
    critic = np.concatenate([policy_obs, observation.privileged_specs(specs)], axis=1)
    np.testing.assert_allclose(state.obs["privileged_state"], critic, atol=1e-6)
    action = jnp.zeros((4, config.action_size))  # the 38 numbers and the search's 9
    after = jax.jit(env.step)(state, action)
    expected = run_trials(
        specs,
        np.asarray(controller_vector(np.zeros((4, config.action_size)), centre)),
        "mujoco",
        config.trial(),
    )
    np.testing.assert_array_equal(after.done, 1.0)
    np.testing.assert_allclose(after.metrics["return"], expected.reward, rtol=1e-6)
    np.testing.assert_allclose(after.reward, expected.reward / 38000.0, rtol=1e-6)
    np.testing.assert_array_equal(after.metrics["success"], expected.success)
    # the same key is the same trial
    again = jax.jit(env.reset)(jax.random.split(jax.random.PRNGKey(1), 4))
    np.testing.assert_array_equal(again.obs["state"], state.obs["state"])
