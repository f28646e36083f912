"""The contact search (skill/search.py): the centre of pressure of a pressed face, the gate, the
goal offsets, the paper's skill untouched, NumPy and JAX alike, and a peg freed from the rim."""

import math

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.skill import search
from mjx_peg.skill.search import SearchConfig

RNG = np.random.default_rng(4)


def _pressed_face(r_xy, n):
    """(..., 6) goal-frame wrench of an axial force n (N) pushing the tip up (goal z is down)
    at the point r_xy (..., 2) of its face (m from the tcp): moment r x F about the tcp."""
    r = np.concatenate([r_xy, np.zeros((*r_xy.shape[:-1], 1))], axis=-1)
    f = np.zeros_like(r)
    f[..., 2] = -n
    return np.concatenate([f, np.cross(r, f)], axis=-1)


def test_centre_of_pressure_is_where_the_face_is_pressed():
    r = RNG.uniform(-0.025, 0.025, (50, 2))
    n = RNG.uniform(5.0, 80.0, 50)
    wrench = _pressed_face(r, n)
    np.testing.assert_allclose(search.centre_of_pressure(wrench, 1.0), r, atol=1e-12)
    # below min_force the division is by min_force: finite in free motion
    light = _pressed_face(r, np.full(50, 0.5))
    np.testing.assert_allclose(search.centre_of_pressure(light, 2.0), r * 0.25, atol=1e-12)


def test_gate_opens_with_the_axial_press_only():
    config = SearchConfig(force_on=10.0, force_full=20.0)
    n = np.array([-50.0, 0.0, 10.0, 15.0, 20.0, 80.0])  # negative: pulling the peg down
    wrench = _pressed_face(np.zeros((6, 2)), n)
    np.testing.assert_allclose(search.resting_gate(config, wrench), [0, 0, 0, 0.5, 1, 1])


def test_centring_moves_the_goal_away_from_the_pressed_side():
    config = SearchConfig(centre_gain=0.8)
    r = np.array([[0.012, -0.005], [0.012, -0.005]])
    wrench = _pressed_face(r, np.array([40.0, 3.0]))  # resting firmly; a touch under f_on
    dy = RNG.normal(0.0, 1e-3, (2, 6))
    out = search.searched_offset(config, dy, wrench)
    np.testing.assert_allclose(out[0, :2], dy[0, :2] - 0.8 * r[0], atol=1e-12)
    np.testing.assert_array_equal(out[1], dy[1])  # the gate is shut: the paper's offset
    np.testing.assert_array_equal(out[:, 2:], dy[:, 2:])


def test_lateral_scale_and_press_bound():
    config = SearchConfig(lateral_scale=0.25, press_accel=2.0)
    dy = RNG.normal(0.0, 1e-3, (1, 6))
    wrench = _pressed_face(np.zeros((1, 2)), np.array([30.0]))
    out = search.searched_offset(config, dy, wrench)
    np.testing.assert_allclose(out[0, :2], 0.25 * dy[0, :2])
    ydd = np.array([[1.0, -2.0, 9.0, 0.1, 0.2, 0.3], [1.0, -2.0, -9.0, 0.1, 0.2, 0.3]])
    bounded = search.bounded_press(config, ydd)
    np.testing.assert_array_equal(bounded[:, 2], [2.0, -9.0])  # into the hole only
    np.testing.assert_array_equal(np.delete(bounded, 2, axis=1), np.delete(ydd, 2, axis=1))


def test_the_paper_skill_is_the_default_and_changes_no_torque():
    from mjx_peg.engines.trial import TrialConfig, control_config

    assert not search.skill_search("paper").active and not TrialConfig().search.active
    assert search.skill_search("search").active
    assert control_config(TrialConfig()).search == search.skill_search("paper")


def test_numpy_and_jax_agree(x64):
    import jax
    import jax.numpy as jnp

    config = SearchConfig(centre_gain=1.0, lateral_scale=0.5, press_accel=3.0)
    wrench = _pressed_face(RNG.uniform(-0.02, 0.02, (8, 2)), RNG.uniform(0.0, 40.0, 8))
    wrench = wrench + RNG.normal(0.0, 0.5, wrench.shape)
    dy, ydd = RNG.normal(0.0, 1e-3, (8, 6)), RNG.normal(0.0, 5.0, (8, 6))

    def both(dy, wrench, ydd):
        return search.searched_offset(config, dy, wrench), search.bounded_press(config, ydd)

    expected = both(dy, wrench, ydd)
    got = jax.jit(both)(jnp.asarray(dy), jnp.asarray(wrench), jnp.asarray(ydd))
    for e, g in zip(expected, got, strict=True):
        np.testing.assert_allclose(np.asarray(g), e, rtol=1e-12, atol=1e-15)


def test_bad_config_and_unknown_skill_are_one_clear_error():
    with pytest.raises(UsageError, match="centre_gain"):
        SearchConfig(centre_gain=-1.0)
    with pytest.raises(UsageError, match="lateral_scale"):
        SearchConfig(lateral_scale=1.5)
    with pytest.raises(UsageError, match="force_on < force_full"):
        SearchConfig(force_on=5.0, force_full=5.0)
    with pytest.raises(UsageError, match="paper, search"):
        search.skill_search("spiral")


def test_centring_frees_pegs_that_the_paper_skill_leaves_on_the_rim():
    """Localization error alone (6 mm, no tilt: the board flat, so the centre of pressure
    points away from the hole): the paper's skill leaves half of these square pegs on the
    rim after 8 s, the centring inserts all of them (measured: 6/12 and 12/12)."""
    from mjx_peg.engines import run_trials
    from mjx_peg.engines.trial import TrialConfig
    from mjx_peg.skill.baseline import baseline_params
    from mjx_peg.world.task import TaskConfig, sample_trials

    task = TaskConfig(shapes=("square",), sizes=(0.05,), linear_error=0.006,
                      angular_error=math.radians(0.0))  # fmt: skip
    specs = sample_trials(task, 5, 12)
    results = {
        name: run_trials(specs, baseline_params(), engine="mujoco", threads=1,
                         config=TrialConfig(time_limit_s=8.0, search=search.skill_search(name)))
        for name in ("paper", "search")
    }  # fmt: skip
    assert results["paper"].success.sum() <= 8
    assert results["search"].success.sum() >= 11
    assert not results["search"].protective_stop.any()
    assert np.median(results["search"].chatter) < 5.0
