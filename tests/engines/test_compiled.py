"""The CPU engine's compiled period: the NumPy pass's numbers, whatever the lanes and slots."""

import numpy as np
import pytest

from mjx_peg.engines import compiled, period, sims
from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines.trial import TrialConfig, as_controller_params, control_config, fitted_basis
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.params import SEARCH_RANGES
from mjx_peg.skill.search import LEARNED, SKILLS
from mjx_peg.world.task import TaskConfig, sample_trials

# One trial config for every compiled run here: its programs compile once per slot count.
CONFIG = TrialConfig(time_limit_s=2.0, search=SKILLS["spiral"])


def _specs(n, seed):
    task = TaskConfig(shapes=("circle", "square", "triangle"), sizes=(0.05, 0.06),
                      linear_error=0.004, angular_error=np.deg2rad(6.0),
                      sensor_noise_scale=(0.5, 2.0), sensor_delay_offset=(-1, 2))  # fmt: skip
    return sample_trials(task, seed, n)


def _params(n):
    rng = np.random.default_rng(0)
    return as_controller_params(np.tile(baseline_params(), (n, 1)) * rng.uniform(0.8, 1.2, (n, 38)),
                                n)  # fmt: skip


class _Captured(Exception):
    pass


def test_the_compiled_period_is_the_numpy_period():
    """One compiled period on a NumPy lane's rows (the spiral skill, in contact at 0.9 s) gives
    the NumPy pass's torques, wrench and state within 1e-9 (relative), its end tests exactly."""
    import jax

    specs, params = _specs(6, seed=4), _params(6)
    got = {}

    def observe(lane, rows, wrench):
        if int(lane.step[0]) == 450:
            copy = lambda a: np.array(a, copy=True)  # noqa: E731
            got.update(m=period.tree_map(copy, lane.measured), n=lane.n,
                       consts=period.tree_map(copy, lane.consts),
                       state=period.tree_map(copy, lane.state))  # fmt: skip
            raise _Captured

    with pytest.raises(_Captured):
        cpu_engine.run_on_cpu(specs, params, CONFIG, threads=1, observer=observe, compiled=False)
    n, size = got["n"], compiled.slot_count(got["n"])
    programs = compiled.programs(CONFIG)
    pad = np.minimum(np.arange(size), n - 1)
    rows = period.tree_map(lambda a: a[pad], got["m"])
    slots = np.arange(size)[::-1]  # row i in slot size - 1 - i
    consts, state = (period.tree_map(lambda a: np.asarray(a)[pad][::-1].copy(), t)
                     for t in (got["consts"], got["state"]))  # fmt: skip
    row_of_slot, slot_of_row = slots.astype(np.int32), slots.astype(np.int32)
    live = np.arange(size)[::-1] < n
    with jax.enable_x64(True):
        state = period.tree_map(
            lambda a: jax.numpy.asarray(a, dtype=np.int32 if a.dtype == np.int64 else a.dtype),
            state,
        )
        new, ended, steps, _, torques, wrench = programs.period(
            consts, state, rows, row_of_slot, slot_of_row, live
        )
        new = period.tree_map(lambda a: np.asarray(a)[slot_of_row[:n]], new)
        ended, steps = np.asarray(ended)[:n], np.asarray(steps)[:n]
        torques, wrench = np.asarray(torques)[:n], np.asarray(wrench)[:n]
    meas = period.tree_map(lambda a: a[:n], sims.period_measurement(got["m"]))
    ref_state, ref_torques, ref_wrench = period.advance(
        CONFIG, control_config(CONFIG), fitted_basis(CONFIG.movement), got["consts"],
        period.tree_map(np.copy, got["state"]), meas,
    )  # fmt: skip
    assert not ended.any() and np.array_equal(steps, got["state"].step)
    assert abs(ref_torques).max() > 1.0  # the arm is held: not a comparison of zeros
    np.testing.assert_allclose(torques, ref_torques, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(wrench, ref_wrench, rtol=1e-9, atol=1e-9)
    flat_ref, flat_new = [], []
    period.tree_map(flat_ref.append, ref_state)
    period.tree_map(flat_new.append, new)
    assert len(flat_ref) == len(flat_new) > 10
    for a, b in zip(flat_ref, flat_new, strict=True):
        np.testing.assert_allclose(np.asarray(b, float), np.asarray(a, float), rtol=1e-9, atol=1e-9)


def test_compiled_results_do_not_depend_on_lanes_or_slots():
    """One lane or two, 3 slots or 40 (32 and 64 compiled slots): bit-identical results, and the
    same outcomes as the NumPy pass on these short trials."""
    specs, params = _specs(12, seed=6), _params(12)
    one = cpu_engine.run_on_cpu(specs, params, CONFIG, threads=1, compiled=True)
    two = cpu_engine.run_on_cpu(specs, params, CONFIG, threads=2, slots_per_thread=3,
                                compiled=True)  # fmt: skip
    wide = cpu_engine.run_on_cpu(specs, params, CONFIG, threads=1, slots_per_thread=40,
                                 compiled=True)  # fmt: skip
    for other in (two, wide):
        for name, value in one.to_arrays().items():
            np.testing.assert_array_equal(getattr(other, name), value, err_msg=name)
    reference = cpu_engine.run_on_cpu(specs, params, CONFIG, threads=1, compiled=False)
    assert 0 < reference.success.sum() < 12, reference.summary()
    np.testing.assert_array_equal(one.success, reference.success)
    np.testing.assert_allclose(one.time_s, reference.time_s, atol=0.05)


def test_a_47_number_policy_runs_alike_on_both_passes():
    """Learned search constants per trial (47 numbers, each within 30 % of the spiral skill's,
    in range): the compiled pass gives the NumPy pass's outcomes and steps, tips within 1e-9 m;
    and they are used (the same 38 numbers alone end elsewhere)."""
    n = 8
    specs, rng = _specs(n, seed=6), np.random.default_rng(1)
    spiral = SKILLS["spiral"]
    low, high = (np.array([SEARCH_RANGES[k][i] for k in LEARNED]) for i in (0, 1))
    search = np.clip([getattr(spiral, k) for k in LEARNED] * rng.uniform(0.7, 1.3, (n, 9)),
                     low, high)  # fmt: skip
    controller = np.tile(baseline_params(), (n, 1)) * rng.uniform(0.8, 1.2, (n, 38))
    params = as_controller_params(np.concatenate([controller, search], axis=1), n)
    numpy_pass = cpu_engine.run_on_cpu(specs, params, CONFIG, threads=1, compiled=False)
    compiled_pass = cpu_engine.run_on_cpu(specs, params, CONFIG, threads=1, compiled=True)
    assert 0 < numpy_pass.success.sum() < n, numpy_pass.summary()
    np.testing.assert_array_equal(compiled_pass.success, numpy_pass.success)
    np.testing.assert_array_equal(compiled_pass.steps, numpy_pass.steps)
    np.testing.assert_allclose(compiled_pass.final_tip_pos, numpy_pass.final_tip_pos, atol=1e-9)
    alone = cpu_engine.run_on_cpu(specs, as_controller_params(controller, n), CONFIG, threads=1,
                                  compiled=False)  # fmt: skip
    assert np.abs(alone.final_tip_pos - numpy_pass.final_tip_pos).max() > 1e-3


def test_a_compiled_lane_leaves_jax_in_float32_and_serves_observers():
    """The compiled lane runs float64 in its own thread's context only; an observer sees its
    live rows' steps and tips as on the NumPy lane."""
    import jax

    specs, params = _specs(2, seed=6), _params(2)
    seen = {False: [], True: []}
    for flag in (False, True):

        def observe(lane, rows, wrench, flag=flag):
            seen[flag].append((int(lane.step[rows[0]]), lane.tip_pos[rows[0]].copy()))

        cpu_engine.run_on_cpu(specs.take([0]), params, CONFIG, threads=1, observer=observe,
                              compiled=flag)  # fmt: skip
    assert not jax.config.jax_enable_x64
    assert jax.numpy.zeros(1).dtype == np.float32
    steps = [s for s, _ in seen[True]]
    assert steps == [s for s, _ in seen[False]] == list(range(len(steps)))
    np.testing.assert_allclose(seen[True][-1][1], seen[False][-1][1], atol=1e-6)


def test_a_sweep_that_follows_the_declared_yaw_uncertainty_runs_alike_on_both_passes():
    """yaw_scale "uncertainty" (each trial's sweep amplitude from its spec's yaw range): on
    squares at +-15 deg and +-6 deg in one batch the compiled pass gives the NumPy pass's outcomes
    and steps, tips within 1e-9 m; against the skill as set the +-15 deg trials end elsewhere,
    the +-6 deg ones (the amplitude exactly as set) bit for bit where they were."""
    from mjx_peg.world.task import TrialSpec

    specs = TrialSpec.concat([sample_trials(TaskConfig(shapes=("square",), linear_error=lin,
                                                       angular_error=np.deg2rad(ang)), 7, 4)
                              for lin, ang in ((0.01, 15.0), (0.004, 6.0))])  # fmt: skip
    params = _params(8)
    config = TrialConfig(time_limit_s=3.0, search=SKILLS["spiral"].replace(yaw_scale="uncertainty"))
    numpy_pass = cpu_engine.run_on_cpu(specs, params, config, threads=1, compiled=False)
    compiled_pass = cpu_engine.run_on_cpu(specs, params, config, threads=1, compiled=True)
    np.testing.assert_array_equal(compiled_pass.success, numpy_pass.success)
    np.testing.assert_array_equal(compiled_pass.steps, numpy_pass.steps)
    np.testing.assert_allclose(compiled_pass.final_tip_pos, numpy_pass.final_tip_pos, atol=1e-9)
    narrow = cpu_engine.run_on_cpu(specs, params, config.replace(search=SKILLS["spiral"]),
                                   threads=1, compiled=False)  # fmt: skip
    moved = np.abs(narrow.final_tip_pos - numpy_pass.final_tip_pos).max(axis=1)
    assert moved[:4].max() > 1e-3
    np.testing.assert_array_equal(moved[4:], 0.0)
    np.testing.assert_array_equal(narrow.time_s[4:], numpy_pass.time_s[4:])
