"""learn/monitor.py: the held-out trials are drawn once from their seed and the policy's mean is
evaluated on them as the engine runs a vector; TensorBoard scalars under their prefix at the
trials seen, nothing when disabled."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjx_peg.engines import run_trials
from mjx_peg.learn import ppo
from mjx_peg.learn.monitor import Board, HeldOut
from mjx_peg.policy import observation
from mjx_peg.world.task import sample_trials

ONE_THREAD = {"threads": 1}


@pytest.fixture(scope="module")
def held_config(tiny_config):
    """The tiny run's config (the hand-tuned start, the centred map) with 4 held-out trials of
    errors up to 1 mm / 1 deg."""
    return tiny_config.replace(eval_trials=4, linear_mm=1.0, angular_deg=1.0, time_limit_s=0.3)


def test_the_held_out_trials_are_drawn_once_from_their_seed(held_config):
    """The same trials whatever the run's seed; another eval_seed other trials; the observation
    of each in the run's layout, float32."""
    a, b = HeldOut(held_config), HeldOut(held_config.replace(seed=held_config.seed + 1))
    other = HeldOut(held_config.replace(eval_seed=held_config.eval_seed + 1))
    assert len(a.specs) == 4
    np.testing.assert_array_equal(a.specs.hole_est_pos, b.specs.hole_est_pos)
    assert not np.array_equal(a.specs.hole_est_pos, other.specs.hole_est_pos)
    width = len(observation.LAYOUTS[held_config.observation])
    assert a.obs.shape == (4, width) and a.obs.dtype == np.float32


def _state_at_the_centre(config):
    """A fresh state whose mean head is zero: its action is 0, the centred map's centre (the
    hand-tuned start) for every observation."""
    state = ppo.init_state(config, ppo.make_networks(config))
    policy = state.params.policy
    head = {k: np.zeros_like(v) for k, v in policy["params"]["Dense_0"].items()}
    policy = {"params": {**policy["params"], "Dense_0": head}}
    return state.replace(params=state.params.replace(policy=policy))


@pytest.mark.parametrize("time_limit_s", [1.0, 0.3])
def test_a_mean_at_the_hand_tuned_start_scores_as_the_engine_runs_it(held_config, time_limit_s):
    """The evaluation of a policy whose mean is the hand-tuned start is the engine's run of
    that vector on the held-out trials, number for number; with no success its time is NaN."""
    config = held_config.replace(time_limit_s=time_limit_s)
    assert config.action_map == "centred"
    held = HeldOut(config, ONE_THREAD)
    scores = held.evaluate(_state_at_the_centre(config))
    specs = sample_trials(config.task(), np.random.default_rng(config.eval_seed), 4)
    vectors = np.broadcast_to(config.prior_vector(), (4, config.action_size))
    result = run_trials(specs, vectors, config.engine, config.trial(), **ONE_THREAD)
    success = np.asarray(result.success, bool)
    assert scores["success_rate"] == success.mean()
    assert scores["mean_return"] == pytest.approx(np.mean(result.reward), rel=1e-12)
    assert scores["protective_stop_rate"] == np.mean(result.protective_stop)
    if time_limit_s == 1.0:  # the hand-tuned start inserts 2 of the 4 within 1 s
        assert success.mean() == 0.5 and scores["time_to_complete_s"] == pytest.approx(
            np.mean(result.time_s[success]), rel=1e-12
        )
    else:  # none within 0.3 s
        assert not success.any() and math.isnan(scores["time_to_complete_s"])


def test_a_board_writes_scalars_at_the_trials_seen(tmp_path, tensorboard_scalars):
    """prefix/NAME at step `trials`; a NaN (no success yet) is left out, not written."""
    board = Board(tmp_path / "tb", enabled=True)
    board.scalars("eval", {"success_rate": 0.25, "time_to_complete_s": float("nan")}, 16)
    board.scalars("eval", {"success_rate": 0.5, "time_to_complete_s": 1.5}, 32)
    board.close()
    tags = tensorboard_scalars(tmp_path / "tb")
    assert tags["eval/success_rate"] == [(16, 0.25), (32, 0.5)]
    assert tags["eval/time_to_complete_s"] == [(32, 1.5)]


def test_a_disabled_board_writes_nothing(tmp_path):
    board = Board(tmp_path / "tb", enabled=False)
    board.scalars("training", {"success_rate": 1.0}, 16)
    board.close()
    assert not (tmp_path / "tb").exists()
