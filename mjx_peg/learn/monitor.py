"""What a run shows while it trains: the policy's mean on held-out trials, TensorBoard scalars.

The exploring policy's success (metrics.csv) is not the exported policy's: its samples carry the
exploration noise. Every `TrainConfig.eval_every` iterations `HeldOut` runs the policy's mean
(Brax's deterministic action) on `eval_trials` trials drawn once from the task with `eval_seed`,
the same trials each time, and the run records them in eval.csv. `Board` writes every metric to
TensorBoard event files (`tensorboardX`, which Brax installs) under RUN_DIR/tensorboard, named
`training/...` for the exploring policy and `eval/...` for the held-out one, as Brax and
Playground name theirs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mjx_peg.engines import run_trials
from mjx_peg.learn import ppo
from mjx_peg.learn.config import TrainConfig
from mjx_peg.policy import network, observation
from mjx_peg.world.task import sample_trials


class HeldOut:
    """The held-out trials of a run and the evaluation of a policy's mean on them."""

    def __init__(self, config: TrainConfig, engine_options: dict | None = None):
        self.config = config
        self.specs = sample_trials(config.task(), np.random.default_rng(config.eval_seed),
                                   config.eval_trials)  # fmt: skip
        self.obs = observation.observe_specs(self.specs, config.observation).astype(np.float32)
        self.engine_options = dict(engine_options or {})

    def evaluate(self, state: ppo.TrainingState) -> dict[str, float]:
        """success_rate, mean_return (paper scale), time_to_complete_s (successes' mean, nan if
        none) and protective_stop_rate of the policy's mean in `state` (unreplicated)."""
        action = np.asarray(ppo.deterministic_actions(self.config, state, self.obs), np.float64)
        vectors = np.asarray(network.controller_vector(action, self.config.map_centre()))
        result = run_trials(self.specs, vectors, self.config.engine, self.config.trial(),
                            **self.engine_options)  # fmt: skip
        success = np.asarray(result.success, bool)
        return {
            "success_rate": float(success.mean()),
            "mean_return": float(np.mean(result.reward)),
            "time_to_complete_s": float(np.mean(result.time_s[success]))
            if success.any()
            else float("nan"),  # fmt: skip
            "protective_stop_rate": float(np.mean(result.protective_stop)),
        }


class Board:
    """TensorBoard scalars of a run (a no-op unless enabled)."""

    def __init__(self, directory: Path, enabled: bool, first_trial: int = 0):
        self.writer = None
        if enabled:
            from tensorboardX import SummaryWriter

            # purge_step: a resumed run drops what the killed one logged after its checkpoint
            self.writer = SummaryWriter(str(directory), purge_step=first_trial or None)

    def scalars(self, prefix: str, values: dict[str, float], trials: int) -> None:
        """values under `prefix/NAME` at step `trials` (the x axis of every curve: trials seen)."""
        if self.writer is None:
            return
        for name, value in values.items():
            if np.isfinite(value):
                self.writer.add_scalar(f"{prefix}/{name}", float(value), trials)
        self.writer.flush()

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()


__all__ = ["Board", "HeldOut"]
