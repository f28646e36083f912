"""Brax PPO on the insertion env: the loop, its state, checkpoints and the run directory.

The loop is composed from Brax's own PPO pieces (`ppo.networks`, `ppo.losses.compute_ppo_loss`,
`gradients.gradient_update_fn`, `acting.actor_step`, `acme.running_statistics`) rather than
`ppo.train`, because `ppo.train` restores neither the optimizer state nor the step count. Here
the whole `TrainingState` (network and value parameters, Adam state, observation statistics,
PRNG key, trials seen, wall time) is one pytree saved with Orbax, so a killed run resumes exactly:
same trial count, same optimizer moments, same random stream, a continuous curve.

One iteration (pmapped over all local devices, axis "i"): every device draws `num_envs / D`
trials (`env.reset`), the policy samples their 38 numbers, the trials run (`env.step`, one
episode step each), the observation statistics are updated, and PPO takes `update_epochs` x
`num_minibatches` gradient steps with gradients averaged across devices. An episode is one step,
so the advantage is the reward minus the value baseline (no bootstrapping).
"""

from __future__ import annotations

import functools
from typing import Any

import flax
import jax
import jax.numpy as jnp
import numpy as np
import optax
from brax.envs.wrappers.training import VmapWrapper
from brax.training import acting, gradients
from brax.training.acme import running_statistics, specs
from brax.training.agents.ppo import losses as ppo_losses
from brax.training.agents.ppo import networks as ppo_networks

from mjx_peg.learn.config import TrainConfig
from mjx_peg.learn.env import METRICS, InsertionEnv, observation_sizes
from mjx_peg.skill.params import (
    DEFAULT_RANGES,
    N_PARAMS,
    action_from_controller,
    controller_from_vector,
)

AXIS = "i"
# Floor of the observation std in Brax's running statistics. Features are already scaled to
# O(1) (observation.py); the floor keeps a feature that is constant in training (the size, the
# triangle flag) from being divided by ~0, so an unseen value stays an O(1) input.
OBS_STD_FLOOR = 1.0
PRIOR_EDGE = 0.95  # fraction of a compliance bound the prior may reach
PRIOR_KERNEL_SCALE = 0.1  # mean-head kernel scale when starting from the prior


@flax.struct.dataclass
class TrainingState:
    """Everything a resumed run needs (one replica; pmapped copies carry a leading device dim)."""

    optimizer_state: optax.OptState
    params: ppo_losses.PPONetworkParams
    normalizer_params: running_statistics.RunningStatisticsState
    key: jax.Array
    trials: jax.Array  # trials seen
    iteration: jax.Array
    wall_s: jax.Array  # training wall time up to this state


def make_networks(config: TrainConfig) -> ppo_networks.PPONetworks:
    """Brax PPO networks: swish MLPs, a Gaussian policy with a learned state-independent std."""
    return ppo_networks.make_ppo_networks(
        observation_sizes(config.observation),
        config.action_size,
        preprocess_observations_fn=running_statistics.normalize,
        policy_hidden_layer_sizes=tuple(config.policy_hidden),
        value_hidden_layer_sizes=tuple(config.value_hidden),
        distribution_type="normal",
        noise_std_type="log",
        init_noise_std=config.init_noise_std,
        policy_obs_key="state",
        value_obs_key="privileged_state",
    )


def make_optimizer(config: TrainConfig) -> optax.GradientTransformation:
    """Adam behind a global gradient-norm clip of 1; with `kl_target` its rate is a state of the
    optimizer (`adapt_learning_rate` sets it), so a resumed run continues at the rate it had."""
    if config.kl_target > 0:
        adam = optax.inject_hyperparams(optax.adam)(learning_rate=config.learning_rate)
    else:
        adam = optax.adam(config.learning_rate)
    return optax.chain(optax.clip_by_global_norm(1.0), adam)


def learning_rate(config: TrainConfig, optimizer_state) -> jax.Array:
    """() the learning rate the next update uses."""
    if config.kl_target > 0:
        return optimizer_state[1].hyperparams["learning_rate"]
    return jnp.asarray(config.learning_rate, jnp.float32)


def adapt_learning_rate(config: TrainConfig, optimizer_state, kl):
    """The optimizer state with its rate divided by 1.5 where the update's mean per-number KL
    `kl` passed 2 kl_target, multiplied by 1.5 where it stayed under kl_target / 2 (the
    adaptive schedule of rl_games' PPO, which Isaac Lab's insertion tasks train with), within
    [learning_rate_min, learning_rate_max]; unchanged without a kl_target."""
    if config.kl_target <= 0:
        return optimizer_state
    inject = optimizer_state[1]
    rate = inject.hyperparams["learning_rate"]
    rate = jnp.where(kl > 2.0 * config.kl_target, rate / 1.5,
                     jnp.where(kl < 0.5 * config.kl_target, rate * 1.5, rate))  # fmt: skip
    rate = jnp.clip(rate, config.learning_rate_min, config.learning_rate_max)
    inject = inject._replace(hyperparams={**inject.hyperparams, "learning_rate": rate})
    return (optimizer_state[0], inject, *optimizer_state[2:])


def context_statistics(config: TrainConfig, normalizer_params):
    """Observation statistics fitted to `config.context_samples` trials drawn from the task
    (seeded by the run's seed): the mean and the std (floored at OBS_STD_FLOOR) of what the
    policy and the critic see. A contextual bandit's observations do not depend on the policy,
    so the statistics need not run: the first update then sees the inputs the last one does."""
    from mjx_peg.policy import observation
    from mjx_peg.world.task import sample_trials

    specs = sample_trials(config.task(), np.random.default_rng([config.seed, 1]),
                          config.context_samples)  # fmt: skip
    obs = observation.observe_specs(specs, config.observation)
    full = np.concatenate([obs, observation.privileged_specs(specs)], axis=-1)
    count = config.context_samples
    mean, std, summed = {}, {}, {}
    for key, x in (("state", obs), ("privileged_state", full)):
        mean[key] = jnp.asarray(x.mean(axis=0), jnp.float32)
        var = x.var(axis=0)
        std[key] = jnp.asarray(np.maximum(np.sqrt(var), OBS_STD_FLOOR), jnp.float32)
        summed[key] = jnp.asarray(var * count, jnp.float32)
    counter = type(normalizer_params.count)
    return normalizer_params.replace(
        count=counter(hi=jnp.uint32(count >> 32), lo=jnp.uint32(count & 0xFFFFFFFF)),
        mean=mean,
        std=std,
        summed_variance=summed,
    )


def prior_action(config: TrainConfig) -> np.ndarray:
    """(38,) or (47,) action of the hand-tuned start (`TrainConfig.prior_vector`): 0 under the
    centred map (its centre); under the sigmoid map its action, the compliance pulled inside the
    ranges (at a range's edge the squashing saturates; at PRIOR_EDGE of the bound the action is
    finite)."""
    if config.action_map == "centred":
        return np.zeros(config.action_size, np.float32)
    vector = config.prior_vector()
    bound = np.asarray(DEFAULT_RANGES.compliance_bound()).reshape(36)
    vector[2:N_PARAMS] = np.clip(vector[2:N_PARAMS], -PRIOR_EDGE * bound, PRIOR_EDGE * bound)
    return np.asarray(action_from_controller(controller_from_vector(vector)), np.float32)


def exploration_scale(config: TrainConfig) -> np.ndarray:
    """(38,) or (47,) the initial exploration std of each number (`init_noise_std` on k_t,
    k_theta, the compliance diagonal and the search's constants, `init_noise_std_coupling` on the
    30 couplings): the unit of the policy's action under `normalized_actions`."""
    diagonal = [True, True] + [i == j for i in range(6) for j in range(6)]
    diagonal += [True] * (config.action_size - N_PARAMS)  # the search's constants
    std = [config.init_noise_std if d else config.init_noise_std_coupling for d in diagonal]
    return np.asarray(std, np.float32)


def action_transform(config: TrainConfig) -> np.ndarray:
    """(A, A) M: the map's action is the network's times M (a row vector times M). Under
    `normalized_actions` the diagonal of exploration scales, and with `joint_stiffness` its
    first two rows mix: k_t's action = s_l level + s_r ratio, k_theta's = s_l level - s_r ratio;
    else the identity. Linear, so the export folds it into the network's head."""
    size = config.action_size
    if not config.normalized_actions:
        return np.eye(size, dtype=np.float32)
    m = np.diag(exploration_scale(config)).astype(np.float32)
    if config.joint_stiffness:
        s_l, s_r = config.init_noise_std_level, config.init_noise_std
        m[0, :2], m[1, :2] = (s_l, s_l), (s_r, -s_r)
    return m


def to_map_action(config: TrainConfig, raw):
    """(..., A) the map's action of the network's (..., A) `raw` (`action_transform`)."""
    return raw @ action_transform(config)


def from_map_action(config: TrainConfig, action):
    """(..., A) the network's action whose map action is `action` (the inverse)."""
    return action @ np.linalg.inv(action_transform(config)).astype(np.float32)


def initial_log_std(config: TrainConfig) -> jax.Array:
    """(38,) or (47,) log of the initial exploration std: `init_noise_std` on k_t, k_theta, the
    compliance diagonal and the search's constants, `init_noise_std_coupling` on the 30
    off-diagonal couplings.

    Measured on 160 trials at +-4 mm / +-6 deg around the baseline: noise of 0.5 on the couplings
    alone halves success (55 % -> 26 %), on the gains and diagonal alone it costs less (-> 40 %),
    and (0.3, 0.1) costs nothing (54 %). Random couplings mostly make the peg wander; a trial
    whose outcome is decided by that noise says little about the mean.
    """
    if config.normalized_actions:  # the network acts in units of the exploration
        return jnp.zeros(config.action_size, jnp.float32)
    return jnp.log(jnp.asarray(exploration_scale(config)))


def cap_exploration(config: TrainConfig, params: ppo_losses.PPONetworkParams, done: int):
    """The params with each number's exploration std held under its decaying cap: after `done`
    of the run's iterations, initial std x std_decay ** (done / iterations), so that by the end
    of the budget the policy explores std_decay times as far as it began (`std_decay` 1: no
    cap). A std the update shrank below its cap stays as it is."""
    if config.std_decay >= 1.0:
        return params
    cap = initial_log_std(config) + jnp.log(config.std_decay) * done / config.iterations
    policy = params.policy["params"]
    log_std = jnp.minimum(policy["std_logparam"]["log_value"], cap)
    policy = {**policy, "std_logparam": {**policy["std_logparam"], "log_value": log_std}}
    return params.replace(policy={**params.policy, "params": policy})


def init_state(config: TrainConfig, networks: ppo_networks.PPONetworks) -> TrainingState:
    """A fresh state from `config.seed` (unreplicated).

    With `config.prior == "baseline"` the policy's mean head starts at the baseline's action
    (bias) with a kernel shrunk by PRIOR_KERNEL_SCALE, so the first policy is the hand-tuned skill
    for every observation plus the exploration noise; "none" keeps Brax's initialization (the
    mid-range controller, ~k = 100 1/s and half the compliance range, varying with the input).
    """
    key = jax.random.PRNGKey(config.seed)
    key, k_policy, k_value = jax.random.split(key, 3)
    policy = networks.policy_network.init(k_policy)
    policy = {
        "params": {**policy["params"], "std_logparam": {"log_value": initial_log_std(config)}}
    }
    head = policy["params"]["Dense_0"]
    if config.prior == "baseline":
        head = {
            "kernel": head["kernel"] * PRIOR_KERNEL_SCALE,
            "bias": jnp.asarray(from_map_action(config, prior_action(config))),
        }
    else:
        head = {**head, "kernel": head["kernel"] * config.head_init_scale}
    policy = {"params": {**policy["params"], "Dense_0": head}}
    params = ppo_losses.PPONetworkParams(
        policy=policy,
        value=networks.value_network.init(k_value),
    )
    sizes = observation_sizes(config.observation)
    obs_spec = {k: specs.Array(v, jnp.dtype("float32")) for k, v in sizes.items()}
    return TrainingState(
        optimizer_state=make_optimizer(config).init(params),
        params=params,
        normalizer_params=running_statistics.init_state(obs_spec),
        key=key,
        trials=jnp.zeros((), jnp.int32),
        iteration=jnp.zeros((), jnp.int32),
        wall_s=jnp.zeros((), jnp.float32),
    )


def make_iteration(env: InsertionEnv, config: TrainConfig):
    """The training iteration, two pmapped programs (the trials, then the update): state ->
    (state, per-trial data, loss metrics).

    pmap spans every device of every process (`jax.device_count()`; one process unless
    `jax.distributed` joined several); each process feeds its local devices. The per-trial data
    are gathered across all devices, so every process sees every trial of the iteration.
    """
    networks = make_networks(config)
    optimizer = make_optimizer(config)
    make_policy = ppo_networks.make_inference_fn(networks)
    per_device = config.num_envs // jax.device_count()
    batched_env = VmapWrapper(env)
    loss_fn = functools.partial(
        ppo_losses.compute_ppo_loss,
        ppo_network=networks,
        entropy_cost=config.entropy_cost,
        discounting=0.0,  # one-step episodes: nothing to discount
        reward_scaling=1.0,
        gae_lambda=1.0,
        clipping_epsilon=config.clipping_epsilon,
        normalize_advantage=True,
    )
    update = gradients.gradient_update_fn(loss_fn, optimizer, pmap_axis_name=AXIS, has_aux=True)

    def minibatch_step(carry, minibatch):
        optimizer_state, params, normalizer_params, key = carry
        key, k_loss = jax.random.split(key)
        (_, metrics), params, optimizer_state = update(
            params, normalizer_params, minibatch, k_loss, optimizer_state=optimizer_state
        )
        return (optimizer_state, params, normalizer_params, key), metrics

    def epoch(carry, _, data):
        optimizer_state, params, normalizer_params, key = carry
        key, k_perm, k_steps = jax.random.split(key, 3)
        perm = jax.random.permutation(k_perm, per_device)
        minibatches = jax.tree.map(
            lambda x: x[perm].reshape((config.num_minibatches, -1) + x.shape[1:]), data
        )
        (optimizer_state, params, _, _), metrics = jax.lax.scan(
            minibatch_step, (optimizer_state, params, normalizer_params, k_steps), minibatches
        )
        return (optimizer_state, params, normalizer_params, key), metrics

    def collect(state: TrainingState):
        """The iteration's trials: the policy acts once per trial, the engine runs them (a host
        callback); the keys the update goes on with."""
        next_key, key = jax.random.split(state.key)
        # Same key on every device, different trials: fold in the device index.
        key = jax.random.fold_in(key, jax.lax.axis_index(AXIS))
        k_reset, k_act, k_sgd = jax.random.split(key, 3)
        env_state = batched_env.reset(jax.random.split(k_reset, per_device))
        policy = make_policy((state.normalizer_params, state.params.policy, state.params.value))
        env_state, transition = acting.actor_step(
            batched_env, env_state, policy, k_act, extra_fields=("truncation",)
        )
        trials = {name: jax.lax.all_gather(env_state.metrics[name], AXIS) for name in METRICS}
        return transition, trials, next_key, k_sgd

    def learn(state: TrainingState, transition, next_key, k_sgd):
        """The PPO update of the iteration's trials: observation statistics, epochs of
        minibatch steps, the exploration cap and the learning rate's adaptation."""
        normalizer_params = state.normalizer_params
        if config.obs_statistics == "running":
            normalizer_params = running_statistics.update(
                normalizer_params,
                transition.observation,
                pmap_axis_name=AXIS,
                std_min_value=OBS_STD_FLOOR,
            )
        data = jax.tree.map(lambda x: x[:, None], transition)  # [B, T=1] as the loss expects
        (optimizer_state, params, _, _), metrics = jax.lax.scan(
            functools.partial(epoch, data=data),
            (state.optimizer_state, state.params, normalizer_params, k_sgd),
            None,
            length=config.update_epochs,
        )
        params = cap_exploration(config, params, state.iteration + 1)
        # the update's KL: the last epoch's, after all but its own last step
        kl = jnp.mean(metrics["kl_mean"][-1])
        metrics = jax.tree.map(jnp.mean, metrics)
        metrics["learning_rate"] = learning_rate(config, optimizer_state)
        optimizer_state = adapt_learning_rate(config, optimizer_state, jax.lax.pmean(kl, AXIS))
        new_state = state.replace(
            optimizer_state=optimizer_state,
            params=params,
            normalizer_params=normalizer_params,
            key=next_key,
            trials=state.trials + config.num_envs,
            iteration=state.iteration + 1,
        )
        return new_state, jax.lax.pmean(metrics, AXIS)

    # Two programs: JAX keeps no program that calls the host in its persistent compilation
    # cache, so the update, apart from the trials' callback, compiles once per machine rather
    # than once per run (~3.5 s here).
    collect_all = jax.pmap(collect, axis_name=AXIS)
    learn_all = jax.pmap(learn, axis_name=AXIS)

    def iteration(state: TrainingState):
        transition, trials, next_key, k_sgd = collect_all(state)
        new_state, metrics = learn_all(state, transition, next_key, k_sgd)
        return new_state, trials, metrics

    return iteration


def replicate(tree: Any) -> Any:
    """One copy of an unreplicated pytree per local device (the leading pmap dim)."""
    n = jax.local_device_count()
    return jax.tree.map(lambda x: np.stack([np.asarray(x)] * n), jax.device_get(tree))


def unreplicate(tree: Any) -> Any:
    """The first replica of a pmapped pytree, on the host."""
    # addressable_shards: with jax.distributed a pmapped output also spans other processes.
    return jax.tree.map(
        lambda x: np.asarray(x.addressable_shards[0].data).reshape(x.shape[1:]), tree
    )


def policy_layers(config: TrainConfig, params: ppo_losses.PPONetworkParams) -> list[tuple]:
    """[(kernel, bias), ...] of the policy MLP's mean path, input to output (NumPy), its head
    times the action scale: the exported network outputs the action the map takes."""
    tree = jax.device_get(params.policy)["params"]
    hidden = tree["MLP_0"]
    layers = [
        (hidden[f"hidden_{i}"]["kernel"], hidden[f"hidden_{i}"]["bias"]) for i in range(len(hidden))
    ]
    m = action_transform(config)
    layers.append((tree["Dense_0"]["kernel"] @ m, tree["Dense_0"]["bias"] @ m))
    return layers


def deterministic_actions(config: TrainConfig, state: TrainingState, obs: jax.Array):
    """(B, 38) or (B, 47): the JAX policy's deterministic action (Brax's inference fn,
    deterministic=True).

    obs: (B, n) policy observations in the run's layout; the critic's input is not used by the
    policy.
    """
    critic = jnp.zeros(obs.shape[:-1] + observation_sizes(config.observation)["privileged_state"],
                       obs.dtype)  # fmt: skip
    obs = {"state": obs, "privileged_state": critic}
    networks = make_networks(config)
    policy = ppo_networks.make_inference_fn(networks)(
        (state.normalizer_params, state.params.policy, state.params.value), deterministic=True
    )
    return to_map_action(config, policy(obs, jax.random.PRNGKey(0))[0])
