"""The compliant DMP: phase, the fitted forcing (minimum jerk, cruise), goal, coupling, damping."""

import dataclasses

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.skill import dmp

CONFIG = dmp.DMPConfig()
Y0 = np.array([0.10, -0.05, 0.20, 0.10, -0.15, 0.08])  # m, m, m, rad, rad, rad
GOAL = np.array([0.02, 0.01, 0.0, 0.0, 0.05, -0.02])


@pytest.fixture(scope="module")
def weights():
    return dmp.fit_forcing_weights(CONFIG)


def test_phase_solves_its_ode():
    t = np.linspace(0.0, 3.0, 3001)
    s = dmp.phase(t, 0.7, 4.0)
    assert s[0] == 1.0
    ds = np.gradient(s, t, edge_order=2)
    np.testing.assert_allclose(0.7 * ds, -4.0 * s, rtol=1e-4, atol=1e-7)


def test_basis_spans_the_movement():
    span = CONFIG.phase_span
    centers, widths = dmp.basis_centers(CONFIG.n_basis, span)
    assert centers.shape == widths.shape == (CONFIG.n_basis,)
    assert centers[0] == 1.0 and np.isclose(centers[-1], np.exp(-span))
    assert np.isclose(centers[-1], dmp.phase(CONFIG.duration, CONFIG.tau, CONFIG.alpha_s))
    assert np.all(np.diff(centers) < 0) and np.all(widths > 0)
    # Centres evenly spaced in time over the movement [0, T].
    np.testing.assert_allclose(np.diff(-np.log(centers)), span / (CONFIG.n_basis - 1))
    np.testing.assert_array_equal(dmp.basis_widths(CONFIG.n_basis, span), widths)


def test_forcing_is_finite_anywhere_in_phase(weights):
    centers, widths = dmp.basis_centers(CONFIG.n_basis, CONFIG.phase_span)
    s = np.array([0.0, 1e-30, 1e-3, 0.5, 1.0, 2.0, 10.0])
    f = dmp.forcing(s, weights, centers, widths)
    assert f.shape == s.shape and np.all(np.isfinite(f))
    assert f[0] == 0.0


def test_fit_is_deterministic():
    np.testing.assert_array_equal(dmp.fit_forcing_weights(CONFIG), dmp.fit_forcing_weights(CONFIG))


def test_free_space_reaches_goal_along_minimum_jerk(weights):
    """F = 0, K = k_ref: within 1 % of the travel of the minimum-jerk path, then at g (1e-4)."""
    k_y = np.full(6, CONFIG.k_ref)
    t, y, _ = dmp.rollout(Y0, GOAL, k_y, CONFIG, weights, duration=4.0 * CONFIG.duration, dt=2e-3)
    p, _, _ = dmp.minimum_jerk(t, CONFIG.duration)
    reference = Y0 + (GOAL - Y0) * p[:, None]
    deviation = np.max(np.abs(y - reference) / np.abs(GOAL - Y0))
    print(f"min-jerk deviation {100 * deviation:.3f} % of travel")
    assert deviation < 0.01
    goal_error = np.abs(y[-1] - GOAL)
    print(f"goal error {goal_error[:3].max():.2e} m, {goal_error[3:].max():.2e} rad")
    assert goal_error.max() < 1e-4


@pytest.mark.parametrize("cruise", [0.25, 0.5, 0.8])
def test_cruise_profile_covers_the_travel_at_its_cruising_speed(cruise):
    """The cruise profile: 0 -> 1 in T, at rest at both ends, its speed and acceleration
    continuous, its speed 2 / (1 + c) travel / T over the middle fraction c (the integrals of pdd
    and pd match pd and p)."""
    duration = 1.5
    t = np.linspace(0.0, duration, 30001)
    p, pd, pdd = dmp.cruise_profile(t, duration, cruise)
    assert p[0] == 0.0 and p[-1] == pytest.approx(1.0, abs=1e-12)
    assert pd[0] == pd[-1] == 0.0 and abs(pdd[0]) < 1e-12 and abs(pdd[-1]) < 1e-12
    np.testing.assert_allclose(np.cumsum(pd[1:] + pd[:-1]) * (t[1] - t[0]) / 2, p[1:], atol=1e-8)
    np.testing.assert_allclose(np.cumsum(pdd[1:] + pdd[:-1]) * (t[1] - t[0]) / 2, pd[1:],
                               atol=1e-7)  # fmt: skip
    middle = np.abs(t / duration - 0.5) <= cruise / 2
    np.testing.assert_allclose(pd[middle], 2.0 / (1.0 + cruise) / duration)
    assert pd.max() == pytest.approx(2.0 / (1.0 + cruise) / duration)
    assert np.max(np.abs(np.diff(pd))) < 1e-3 and np.max(np.abs(np.diff(pdd))) < 1e-2
    assert np.all(pd >= 0.0)
    minimum_jerk_peak = dmp.minimum_jerk(t, duration)[1].max()
    assert pd.max() < minimum_jerk_peak  # 1.875 travel / T


def test_free_space_follows_the_cruise_and_reaches_goal():
    """F = 0, K = k_ref, a cruising movement (c = 0.5, T = 1.5 s): within 1 % of the travel of
    its profile, at the goal (1e-4) after; the minimum-jerk path of T differs by > 2 %."""
    config = dataclasses.replace(CONFIG, duration=1.5, cruise=0.5)
    k_y = np.full(6, config.k_ref)
    w = dmp.fit_forcing_weights(config)
    t, y, _ = dmp.rollout(Y0, GOAL, k_y, config, w, duration=6.0, dt=2e-3)
    travel = np.abs(GOAL - Y0)
    profile = Y0 + (GOAL - Y0) * dmp.movement_profile(t, config)[0][:, None]
    assert np.max(np.abs(y - profile) / travel) < 0.01
    assert np.abs(y[-1] - GOAL).max() < 1e-4
    jerk_path = Y0 + (GOAL - Y0) * dmp.minimum_jerk(t, 1.5)[0][:, None]
    assert np.max(np.abs(y - jerk_path) / travel) > 0.02
    with pytest.raises(UsageError, match="cruise"):
        dmp.DMPConfig(cruise=1.0)


@pytest.mark.parametrize("k", [30.0, 300.0, 1000.0])
def test_other_stiffness_still_converges(weights, k):
    t, y, _ = dmp.rollout(Y0, GOAL, np.full(6, k), CONFIG, weights, duration=6.0, dt=2e-3)
    assert np.abs(y[-1] - GOAL).max() < 1e-4
    # With the stiffness-scaled forcing no stiffness drives the tcp back past y0 by more than the
    # regression error of the fit near s = 1 (0.2 % of the travel at the defaults).
    progress = (y - Y0) / (GOAL - Y0)
    assert progress.min() > -0.005


def test_constant_wrench_settles_at_goal_plus_compliance_offset(weights):
    rng = np.random.default_rng(0)
    compliance = np.diag([8e-4, 5e-4, 2e-4, 0.03, 0.02, 0.01]) + 1e-5 * rng.normal(size=(6, 6))
    wrench = np.array([10.0, -5.0, 20.0, 0.5, -1.0, 0.2])
    k_y = dmp.stiffness_diag(200.0, 50.0)
    _, y, _ = dmp.rollout(Y0, GOAL, k_y, CONFIG, weights, compliance, wrench, duration=10.0)
    expected = GOAL + compliance @ wrench
    np.testing.assert_allclose(y[-1], expected, rtol=0, atol=1e-7)


def test_off_diagonal_compliance_couples_exactly(weights):
    """A force along x moves the goal along each coupled axis j by exactly C[j, 0] F_x."""
    compliance = np.diag([5e-4, 5e-4, 5e-4, 0.02, 0.02, 0.02])
    compliance[2, 0] = -3e-4  # x force -> z yield
    compliance[4, 0] = 2e-3  # x force -> tilt about y
    wrench = np.array([15.0, 0, 0, 0, 0, 0])
    k_y = dmp.stiffness_diag(300.0, 100.0)
    _, y, _ = dmp.rollout(Y0, GOAL, k_y, CONFIG, weights, compliance, wrench, duration=10.0)
    offset = y[-1] - GOAL
    for j in (0, 2, 4):
        expected = compliance[j, 0] * wrench[0]
        print(
            f"axis {j}: offset {offset[j]:.9g}, C F {expected:.9g}, "
            f"rel {offset[j] / expected - 1:.1e}"
        )
        np.testing.assert_allclose(offset[j], expected, rtol=1e-6)
    np.testing.assert_allclose(offset[[1, 3, 5]], 0.0, atol=1e-9)


def test_coupling_term_equals_modified_goal_form():
    """Eq. 8 (spring + forcing + c_c) and Eq. 10 (PD towards g_m) are the same acceleration.

    With the forcing scaled by K_y / k_ref (`scaled_modified_goal`), Eq. 8's forcing term is
    (g - y0) f K_y / k_ref; at K_y = k_ref it is the paper's literal form.
    """
    rng = np.random.default_rng(1)
    y, yd, g, y0 = rng.normal(size=(4, 7, 6))
    f = rng.normal(size=7)
    k_y = dmp.stiffness_diag(rng.uniform(10, 1000, 7), rng.uniform(10, 1000, 7))
    d_y = dmp.critical_damping(k_y, 0.8)
    compliance, wrench = rng.normal(size=(7, 6, 6)), rng.normal(size=(7, 6))
    c_c = dmp.coupling_term(k_y, compliance, wrench)
    k_ref = 250.0
    eq8 = (k_y * (g - y) - d_y * yd + (g - y0) * f[:, None] * k_y / k_ref + c_c) / 0.8
    g_m = dmp.scaled_modified_goal(g, y0, f, k_ref, dmp.compliance_offset(compliance, wrench))
    np.testing.assert_allclose(dmp.dmp_acceleration(y, yd, g_m, k_y, d_y, 0.8), eq8, rtol=1e-12)


@pytest.mark.parametrize("tau", [0.5, 1.0, 2.0])
def test_critical_damping_step_has_no_overshoot(tau):
    """Unforced (f = 0) step of every axis, stiffnesses across the learned range."""
    config = dataclasses.replace(CONFIG, tau=tau)
    worst = -np.inf
    for k_t, k_theta in ((10.0, 1000.0), (100.0, 30.0), (1000.0, 10.0)):
        k_y = dmp.stiffness_diag(k_t, k_theta)
        _, y, _ = dmp.rollout(Y0, GOAL, k_y, config, None, duration=15.0 * tau, dt=1e-3)
        progress = (y - Y0) / (GOAL - Y0)  # 0 -> 1 per axis
        worst = max(worst, progress.max() - 1.0)
        assert np.abs(progress[-1] - 1.0).max() < 1e-4
    print(f"tau {tau}: largest progress - 1 = {worst:.2e} of the step")
    assert worst < 1e-6


def test_critical_damping_gives_a_double_root():
    """tau l^2 + D l + K = 0 has discriminant D^2 - 4 tau K = 0 for every axis."""
    k = np.array([10.0, 50.0, 100.0, 300.0, 1000.0, 1.0])
    for tau in (0.3, 1.0, 3.0):
        d = dmp.critical_damping(k, tau)
        np.testing.assert_allclose(d * d - 4.0 * tau * k, 0.0, atol=1e-9)


def test_stiffness_diag_broadcasts():
    k = dmp.stiffness_diag(np.array([1.0, 2.0]), 3.0)
    np.testing.assert_array_equal(k, [[1, 1, 1, 3, 3, 3], [2, 2, 2, 3, 3, 3]])


@pytest.mark.parametrize(
    "changes", [{"n_basis": 1}, {"alpha_s": 0.0}, {"tau": -1.0}, {"k_ref": float("nan")}]
)
def test_bad_config_raises(changes):
    with pytest.raises(ValueError, match="DMPConfig"):
        dmp.DMPConfig(**changes)
