"""The insertion task as a Brax environment: one trial is one environment step.

The paper's learning problem (sections 4.3, 6.1) is a contextual bandit: the policy sees the
estimated hole pose, the shape and the size (`observation.py`), outputs the 38 controller
numbers once, and the trial that follows earns the reward. So `reset` draws a `TrialSpec` and
returns its observation, and `step` runs the whole trial and ends the episode (`done` = 1).

The observation is a dict: "state" for the policy (`observation.observe_part`, in the run's
layout, `TrainConfig.observation`) and "privileged_state" for the critic only (that plus the
true errors and friction, `observation.privileged`): an asymmetric actor-critic, the policy never
sees the true errors.

The physics runs on the host: `reset` and `step` call NumPy through `jax.pure_callback`, and
under `jax.vmap` the callback sees the whole batch at once, so one `run_trials` call runs every
trial of a training iteration through the engine's queue. A trial is defined by its 64-bit seed
(two uint32 in `state.info["seed"]`): reset and step both rebuild the spec from it in float64, so
nothing of the spec is rounded through float32 and the same key always gives the same trial.

Reward: the paper's scale (38000 on success, else shaped by the tip's progress) divided by 38000,
so it lies in [0, 1]; `metrics` carry the paper-scale return, success and time to complete.
"""

from __future__ import annotations

import contextlib
import io

import jax
import jax.numpy as jnp
import numpy as np

# Importing brax imports mujoco.mjx, whose Warp backend prints "Failed to import warp" on every
# machine without Warp (all CPU ones): keep that line out of the CLIs' output.
with contextlib.redirect_stdout(io.StringIO()):
    from brax.envs.base import Env, State

from mjx_peg.engines import resolve_engine, run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.policy import network, observation
from mjx_peg.skill.params import N_LEARNED, N_PARAMS, check_centre
from mjx_peg.world.task import TaskConfig, TrialSpec, sample_trials

# Per trial: the outcome, how a failure ended (unstable, settled, protective stop) and the
# contact metrics (TrialResult: peak sensed force, N; chatter of the true axial force, N).
METRICS = ("return", "success", "time_s", "unstable", "settled", "protective_stop", "peak_force",
           "chatter")  # fmt: skip
OBS_KEYS = ("state", "privileged_state")


def observation_sizes(layout: str) -> dict[str, tuple[int]]:
    """{"state": what the policy (and the robot) sees in `layout`; "privileged_state": the
    critic's input, the same plus the trial's true errors and friction (observation.privileged),
    used only in training} -> their (size,)."""
    width = len(observation.LAYOUTS[observation.check_layout(layout)])
    return {"state": (width,), "privileged_state": (width + len(observation.PRIVILEGED_NAMES),)}


def specs_from_seeds(task: TaskConfig, seeds: np.ndarray) -> TrialSpec:
    """One trial per (2,) uint32 seed row; the same row always gives the same trial."""
    seeds = np.asarray(seeds, dtype=np.uint32).reshape(-1, 2)
    return TrialSpec.concat(
        [sample_trials(task, np.random.default_rng(row.tolist()), 1) for row in seeds]
    )


class InsertionEnv(Env):
    """Brax `Env`: reset draws a trial, step runs it to the end with the action's controller."""

    def __init__(
        self,
        task: TaskConfig | None = None,
        trial: TrialConfig | None = None,
        engine: str = "mujoco",
        engine_options: dict | None = None,
        action_centre=None,
        layout: str = observation.DEFAULT_LAYOUT,
        action_size: int = N_PARAMS,
        action_transform=None,
    ):
        self.task = task or TaskConfig()
        self.trial = trial or TrialConfig(time_limit_s=self.task.time_limit_s)
        self.engine = resolve_engine(engine)
        self.engine_options = dict(engine_options or {})
        # the centred map's (38,) centre, or None for the sigmoid map (network.controller_vector)
        self.action_centre = None if action_centre is None else check_centre(action_centre)
        if action_size not in (N_PARAMS, N_LEARNED):
            raise ValueError(f"action_size {action_size}: {N_PARAMS} or {N_LEARNED}")
        if self.action_centre is not None and self.action_centre.size != action_size:
            raise ValueError(f"a centre of {self.action_centre.size} numbers, actions of "
                             f"{action_size}")  # fmt: skip
        self._action_size = action_size
        # (A, A): the map's action is the network's times it (learn.ppo.action_transform)
        self.action_transform = (
            None if action_transform is None else np.asarray(action_transform, np.float32)
        )
        self.layout = layout  # the policy's observation layout (observation.LAYOUTS)
        self.sizes = observation_sizes(layout)
        self._last_specs: tuple[bytes, TrialSpec] | None = None  # reset's draw, reused by step

    def _specs(self, seeds: np.ndarray) -> TrialSpec:
        """specs_from_seeds, remembered for the last seeds: reset and step of one iteration
        draw the same trials, and the draw (one rejection-sampled IK per trial) is serial."""
        key = np.ascontiguousarray(seeds, dtype=np.uint32).tobytes()
        if self._last_specs is None or self._last_specs[0] != key:
            self._last_specs = (key, specs_from_seeds(self.task, seeds))
        return self._last_specs[1]

    @property
    def observation_size(self) -> dict[str, tuple[int]]:
        return self.sizes

    @property
    def action_size(self) -> int:
        return self._action_size

    @property
    def backend(self) -> str:
        return self.engine

    # Host side (NumPy). Called with a leading batch dim under vmap, without one otherwise.
    def _observe_host(self, seeds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        specs = self._specs(seeds)
        obs = observation.observe_specs(specs, self.layout)
        full = np.concatenate([obs, observation.privileged_specs(specs)], axis=-1)
        batch = np.shape(seeds)[:-1]
        return (
            obs.astype(np.float32).reshape(batch + self.sizes["state"]),
            full.astype(np.float32).reshape(batch + self.sizes["privileged_state"]),
        )

    def _run_host(self, seeds: np.ndarray, vectors: np.ndarray):
        batch = np.shape(seeds)[:-1]
        specs = self._specs(seeds)
        params = np.asarray(vectors, dtype=np.float64).reshape(-1, self._action_size)
        result = run_trials(specs, params, self.engine, self.trial, **self.engine_options)
        out = (
            result.reward,
            result.success,
            np.where(result.success, result.time_s, np.nan),
            result.unstable,
            result.settled,
            result.protective_stop,
            result.peak_force,
            result.chatter,
        )
        return tuple(np.asarray(x, np.float32).reshape(batch) for x in out)

    def reset(self, rng: jax.Array) -> State:
        seed = jax.random.bits(rng, (2,), jnp.uint32)
        state, privileged = jax.pure_callback(
            self._observe_host,
            tuple(jax.ShapeDtypeStruct(self.sizes[k], jnp.float32) for k in OBS_KEYS),
            seed,
            vmap_method="broadcast_all",
        )
        obs = {"state": state, "privileged_state": privileged}
        zero = jnp.zeros((), jnp.float32)
        return State(
            pipeline_state=None,
            obs=obs,
            reward=zero,
            done=zero,
            metrics={name: zero for name in METRICS},
            info={"seed": seed, "truncation": zero},
        )

    def step(self, state: State, action: jax.Array) -> State:
        if self.action_transform is not None:
            action = action @ self.action_transform
        vector = network.controller_vector(action, self.action_centre)
        scalar = jax.ShapeDtypeStruct((), jnp.float32)
        outcome = jax.pure_callback(
            self._run_host,
            (scalar,) * len(METRICS),
            state.info["seed"],
            vector,
            vmap_method="broadcast_all",
        )
        metrics = dict(zip(METRICS, outcome, strict=True))
        return state.replace(
            reward=metrics["return"] / self.trial.reward.success,
            done=jnp.ones((), jnp.float32),
            metrics=metrics,
        )
