"""The 38-parameter map: every action is a valid controller, round trips, names and units."""

import numpy as np
import pytest

from mjx_peg.skill import params as P

RANGES = P.DEFAULT_RANGES
BOUND = np.array(RANGES.compliance_bound())
DIAG = np.eye(6, dtype=bool)


def _assert_valid(p: P.ControllerParams):
    """Positive finite gains, finite compliance within the ranges (up to the dtype's rounding)."""
    rel = 4 * np.finfo(p.compliance.dtype).eps
    for k, (lo, hi) in ((p.k_t, RANGES.k_t), (p.k_theta, RANGES.k_theta)):
        assert np.all(np.isfinite(k)) and np.all(k > 0)
        assert np.all(k >= lo * (1 - rel)) and np.all(k <= hi * (1 + rel))
    c = p.compliance
    assert np.all(np.isfinite(c))
    assert np.all(c[..., DIAG] >= 0.0)
    assert np.all(np.abs(c) <= BOUND * (1 + rel))


def test_names_units_and_count():
    assert P.N_PARAMS == 38 == len(P.PARAM_NAMES) == len(P.PARAM_UNITS)
    assert P.PARAM_NAMES[:3] == ("k_t", "k_theta", "C[0,0]") and P.PARAM_NAMES[-1] == "C[5,5]"
    assert len(set(P.PARAM_NAMES)) == 38
    assert P.PARAM_UNITS[2 + 6 * 0 + 3] == "m/(N m)" and P.PARAM_UNITS[2 + 6 * 4 + 1] == "rad/N"


def test_ranges_from_the_docstring():
    assert BOUND[0, 0] == 2e-3 and BOUND[5, 5] == 0.1
    np.testing.assert_allclose(BOUND[0, 1], 1e-3)
    np.testing.assert_allclose(BOUND[3, 4], 0.05)
    np.testing.assert_allclose(BOUND[0, 3], 0.5 * np.sqrt(2e-3 * 0.1))
    np.testing.assert_allclose(BOUND, BOUND.T)


@pytest.mark.parametrize("value", [1e6, -1e6, 0.0, 1e300, -1e300])
def test_extreme_actions_are_valid_controllers(value):
    p = P.controller_from_action(np.full(38, value))
    _assert_valid(p)


def test_mixed_sign_extremes_and_wide_random_actions_are_valid():
    rng = np.random.default_rng(0)
    signs = rng.choice([-1e6, 1e6], size=(64, 38))
    wide = rng.normal(scale=100.0, size=(256, 38))
    for action in (signs, wide, wide.astype(np.float32)):
        with np.errstate(all="raise"):  # no overflow anywhere in the squashing
            p = P.controller_from_action(action)
        _assert_valid(p)
        assert p.compliance.dtype == action.dtype


def test_saturated_ends_hit_the_range_edges():
    p_hi = P.controller_from_action(np.full(38, 1e6))
    p_lo = P.controller_from_action(np.full(38, -1e6))
    assert p_hi.k_t == pytest.approx(1000.0) and p_lo.k_theta == pytest.approx(10.0)
    np.testing.assert_allclose(p_hi.compliance, BOUND)
    np.testing.assert_allclose(p_lo.compliance, np.where(DIAG, 0.0, -BOUND))


def test_zero_action_is_the_middle():
    p = P.controller_from_action(np.zeros(38))
    assert p.k_t == pytest.approx(100.0)  # geometric mean of 10 and 1000
    np.testing.assert_allclose(p.compliance, np.where(DIAG, BOUND / 2, 0.0), atol=1e-18)


def test_round_trip_in_a_moderate_box():
    rng = np.random.default_rng(1)
    action = rng.uniform(-3.0, 3.0, size=(500, 38))
    back = P.action_from_controller(P.controller_from_action(action))
    err = np.abs(back - action).max()
    print(f"action round trip max error {err:.2e}")
    assert err < 1e-6


def test_action_of_an_edge_value_is_finite():
    p = P.controller_from_action(np.full(38, -1e6))  # diagonal compliance exactly 0
    back = P.action_from_controller(p)
    assert np.all(np.isfinite(back))
    _assert_valid(P.controller_from_action(back))


def test_vector_round_trip_and_layout():
    rng = np.random.default_rng(2)
    p = P.controller_from_action(rng.normal(size=(3, 4, 38)))
    v = P.vector_from_controller(p)
    assert v.shape == (3, 4, 38)
    np.testing.assert_array_equal(v[..., 0], p.k_t)
    np.testing.assert_array_equal(v[..., 2 + 6 * 2 + 5], p.compliance[..., 2, 5])
    q = P.controller_from_vector(v)
    for a, b in zip(p, q, strict=True):
        np.testing.assert_array_equal(a, b)


def test_wrong_length_raises():
    with pytest.raises(ValueError, match="38"):
        P.controller_from_action(np.zeros(37))


def test_bad_ranges_raise():
    with pytest.raises(ValueError, match="k_t"):
        P.ParamRanges(k_t=(0.0, 10.0))
    with pytest.raises(ValueError, match="rot_compliance_max"):
        P.ParamRanges(rot_compliance_max=-1.0)


def test_stiffness_from_compliance():
    rng = np.random.default_rng(3)
    p = P.controller_from_action(rng.normal(size=(5, 38)))
    k_c = P.stiffness_from_compliance(p.compliance)
    np.testing.assert_allclose(k_c @ p.compliance, np.broadcast_to(np.eye(6), (5, 6, 6)), atol=1e-8)
    stiff_z = np.diag([1e-3, 1e-3, 0.0, 0.05, 0.05, 0.05])  # z infinitely stiff: no finite K_c
    with pytest.raises(ValueError, match="singular"):
        P.stiffness_from_compliance(stiff_z)


# The centred map: action 0 is the baseline, sensitive in both directions there.


def _centre():
    from mjx_peg.skill.baseline import baseline_params

    return P.check_centre(baseline_params())


@pytest.mark.parametrize("value", [1e6, -1e6, 1e300, -1e300])
def test_centred_map_is_valid_for_any_action(value):
    _assert_valid(P.controller_from_centred_action(np.full(38, value), _centre()))
    rng = np.random.default_rng(3)
    _assert_valid(P.controller_from_centred_action(rng.normal(scale=5, size=(500, 38)), _centre()))


def test_centred_map_is_the_centre_at_zero_and_round_trips():
    centre = _centre()
    at_zero = P.vector_from_controller(P.controller_from_centred_action(np.zeros(38), centre))
    np.testing.assert_allclose(at_zero, centre, rtol=1e-12, atol=1e-18)
    action = np.random.default_rng(4).uniform(-2, 2, size=(200, 38))
    p = P.controller_from_centred_action(action, centre)
    back = P.centred_action_from_controller(p, centre)
    again = P.controller_from_centred_action(back, centre)
    np.testing.assert_allclose(P.vector_from_controller(again), P.vector_from_controller(p),
                               rtol=1e-9, atol=1e-15)  # fmt: skip


def test_exploration_moves_the_baseline_under_the_centred_map_not_the_sigmoid_one():
    """The baseline's k_t = 900 of [10, 1000] and C_xx = 1.8e-3 of 2e-3: an action step of -0.4
    (the exploration std) moves them 37 % and 11 % down under the centred map, 4 % under the
    sigmoid map from the baseline's action there (the trap PPO sat in)."""
    from mjx_peg.learn.config import TrainConfig
    from mjx_peg.learn.ppo import prior_action

    step = np.zeros(38)
    step[[0, 2]] = -0.4
    centred = P.vector_from_controller(P.controller_from_centred_action(step, _centre()))
    prior = prior_action(TrainConfig(action_map="sigmoid", learn_search=False)).astype(np.float64)
    sigmoid_0 = P.vector_from_controller(P.controller_from_action(prior))
    sigmoid = P.vector_from_controller(P.controller_from_action(prior + step))
    centre = _centre()
    u0 = np.log(90) / np.log(100)  # u = u0 + u0 tanh(s a / u0), s = 1/4, a = -0.4
    assert centred[0] == pytest.approx(10 * 100 ** (u0 + u0 * np.tanh(-0.1 / u0)), rel=1e-9)
    assert centred[2] == pytest.approx(2e-3 * (0.9 + 0.9 * np.tanh(-0.1 / 0.9)), rel=1e-9)
    assert centred[0] / centre[0] < 0.65 and centred[2] / centre[2] < 0.9
    assert sigmoid[0] / sigmoid_0[0] > 0.95 and sigmoid[2] / sigmoid_0[2] > 0.95


def test_a_centre_on_an_edge_is_refused():
    centre = _centre()
    for i, value in ((0, 1000.0), (2, 0.0), (2 + 4, 0.5 * np.sqrt(2e-3 * 0.1))):
        bad = centre.copy()
        bad[i] = value
        with pytest.raises(ValueError, match=P.PARAM_NAMES[i].replace("[", r"\[")):
            P.check_centre(bad)


# -- the contact search's learned constants (47 numbers) -------------------------------------------

SEARCH_LOW = np.array([P.SEARCH_RANGES[n][0] for n in P.LEARNED_NAMES[38:]])
SEARCH_HIGH = np.array([P.SEARCH_RANGES[n][1] for n in P.LEARNED_NAMES[38:]])


def test_the_search_constants_follow_the_38_with_names_units_and_ranges():
    assert P.N_LEARNED == 47 == len(P.LEARNED_NAMES) == len(P.LEARNED_UNITS)
    assert P.LEARNED_NAMES[:38] == P.PARAM_NAMES
    assert P.LEARNED_NAMES[38:] == ("spiral_pitch", "spiral_radius", "spiral_speed",
                                    "spiral_axial", "align_rate", "align_depth",
                                    "insert_depth", "insert_axial", "movement_s")  # fmt: skip
    assert np.all(SEARCH_LOW < SEARCH_HIGH)


@pytest.mark.parametrize("value", [1e6, -1e6, 0.0])
def test_every_action_of_47_is_a_controller_and_a_search_within_its_ranges(value):
    p = P.controller_from_action(np.full(47, value))
    _assert_valid(p)
    s = P.vector_from_search(p.search)
    assert np.all(s >= SEARCH_LOW) and np.all(s <= SEARCH_HIGH)
    if value == 0.0:  # the middle: geometric for log-scaled ranges, arithmetic otherwise
        logged = np.array([P.SEARCH_RANGES[n][2] for n in P.LEARNED_NAMES[38:]])
        middle = np.where(logged, np.sqrt(SEARCH_LOW * SEARCH_HIGH), (SEARCH_LOW + SEARCH_HIGH) / 2)
        np.testing.assert_allclose(s, middle, rtol=1e-12)


def test_the_47_vector_round_trips_through_both_maps():
    rng = np.random.default_rng(3)
    action = rng.normal(scale=1.5, size=(32, 47))
    vector = np.asarray(P.vector_from_controller(P.controller_from_action(action)))
    assert vector.shape == (32, 47)
    back = np.asarray(P.action_from_controller(P.controller_from_vector(vector)))
    np.testing.assert_allclose(back, action, atol=1e-8)
    # a centre well inside the ranges, actions where tanh does not saturate
    centre = P.vector_from_controller(P.controller_from_action(0.3 * action[0]))
    moderate = np.clip(action, -1.0, 1.0)
    moved = P.vector_from_controller(P.controller_from_centred_action(moderate, centre))
    zero = P.vector_from_controller(P.controller_from_centred_action(np.zeros(47), centre))
    np.testing.assert_allclose(zero, centre, rtol=1e-12)
    again = P.centred_action_from_controller(P.controller_from_vector(moved), centre)
    np.testing.assert_allclose(again, moderate, atol=1e-6)


def test_a_centre_of_38_refuses_actions_of_47():
    centre = P.vector_from_controller(P.controller_from_action(np.zeros(38)))
    with pytest.raises(ValueError, match="centre of 38"):
        P.controller_from_centred_action(np.zeros(47), centre)
