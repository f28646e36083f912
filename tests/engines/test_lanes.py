"""engines/lanes.py: trials in lanes of this process give the same results, bit for bit, however
many lanes, slots and C threads; the queue hands each trial out once; a failing lane is one
error."""

import threading

import numpy as np
import pytest

from mjx_peg.engines import lanes, period, run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.skill.baseline import baseline_params


def test_results_do_not_depend_on_lanes_slots_or_batch_threads(mixed_specs):
    """One lane or two, few slots or many, 1 or 2 C threads per batch: bit-identical results,
    progress for every trial (slots recycled across scenes), the batches reused across calls."""
    from mjx_peg.engines import sims

    specs = mixed_specs(12, seed=6)
    params = np.tile(baseline_params(), (12, 1))
    params[5, :2] = 1e9  # one trial blows up
    config = TrialConfig(time_limit_s=3.0)  # the approach takes 2 s
    counts = []
    lanes = run_trials(
        specs, params, engine="mujoco", config=config, threads=2, slots_per_thread=3,
        progress=counts.append,
    )  # fmt: skip
    assert sum(counts) == 12
    local = run_trials(specs, params, engine="mujoco", config=config, threads=1)
    assert local.unstable[5] and 0 < local.success.sum() < 12, local.summary()
    cached = {id(s) for s in sims.pooled()}
    again = run_trials(specs, params, engine="mujoco", config=config, threads=1)
    assert {id(s) for s in sims.pooled()} == cached
    threaded = run_trials(specs, params, engine="mujoco", config=config, threads=1, batch_threads=2)
    one_data = run_trials(specs, params, engine="mujoco", config=config, persistent=False)
    data_each = run_trials(specs, params, engine="mujoco", config=config, persistent=True)
    for other in (lanes, again, threaded, one_data, data_each):
        for name, value in local.to_arrays().items():
            np.testing.assert_array_equal(getattr(other, name), value, err_msg=name)


def test_an_error_in_a_lane_is_one_clear_error(monkeypatch, mixed_specs):
    """A lane that fails stops the call with its exception in the caller; the next call runs."""
    from mjx_peg.engines import period

    specs = mixed_specs(8, seed=7)
    config = TrialConfig(time_limit_s=0.5)
    calls, original = [0], period.skill_torque

    def failing(*args):
        calls[0] += 1
        if calls[0] == 30:
            raise RuntimeError("controller failed")
        return original(*args)

    monkeypatch.setattr(period, "skill_torque", failing)
    with pytest.raises(RuntimeError, match="controller failed"):
        run_trials(specs, baseline_params(), engine="mujoco", config=config, threads=2)
    monkeypatch.setattr(period, "skill_torque", original)
    result = run_trials(specs, baseline_params(), engine="mujoco", config=config, threads=2)
    assert len(result) == 8 and result.steps.min() > 0


def _outcome(k: int) -> period.Outcome:
    """k ended trials: successes taking 2 steps each, tips at the origin."""
    return period.Outcome(
        success=np.ones(k, bool), final_tip_pos=np.zeros((k, 3)), peak_force=np.full(k, 5.0),
        reward=np.full(k, 38000.0), unstable=np.zeros(k, bool), steps=np.full(k, 2),
        settled=np.zeros(k, bool), chatter=np.zeros(k), protective_stop=np.zeros(k, bool),
    )  # fmt: skip


def test_the_queue_hands_out_each_trial_once_and_reports_every_result():
    reported = []
    queue = lanes.Queue(50, reported.append)
    taken, lock = [], threading.Lock()

    def take_all():
        while (index := queue.take()) is not None:
            with lock:
                taken.append(index)

    workers = [threading.Thread(target=take_all) for _ in range(4)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    assert sorted(taken) == list(range(50))  # four lanes, each trial once
    queue.finish(np.array([3, 7]), _outcome(2), np.array([1.5, 2.5]))
    queue.finish(np.array([0]), _outcome(1), np.array([0.5]))
    queue.flush()
    queue.flush()  # nothing new: no call
    assert reported == [3]
    result = lanes.to_result(queue.records)
    np.testing.assert_array_equal(result.time_s[[0, 3, 7]], [0.5, 1.5, 2.5])
    assert result.success[[0, 3, 7]].all() and result.success.sum() == 3
    stopped = lanes.Queue(5, None)
    assert stopped.take() == 0
    stopped.stop()
    assert stopped.stopped and stopped.take() is None


def test_a_lane_option_is_a_positive_integer():
    assert lanes.count("threads", None, 3) == 3
    assert lanes.count("threads", np.int64(2), 1) == 2
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="threads must be a positive integer"):
            lanes.count("threads", bad, 1)
