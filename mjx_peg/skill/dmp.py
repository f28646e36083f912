"""Compliant Cartesian DMP (paper sections 3-4), written by hand: no library offers the coupling.

The discrete dynamic movement primitive of Ijspeert, Nakanishi, Hoffmann, Pastor & Schaal,
"Dynamical movement primitives: learning attractor models for motor behaviors", Neural
Computation 25(2), 2013, in the form used by Spector & Zacksenhouse (equation numbers of the
paper, /work/shared/paper):

    phase          tau ds/dt = -alpha_s s,  s(0) = 1                                   (Eq. 2)
    forcing        f(s) = sum_i psi_i w_i / sum_i psi_i * s,
                   psi_i = exp(-(s - c_i)^2 / (2 sigma_i^2))                          (Eqs. 3, 4)
    DMP            tau ydd = K_y (g - y) - D_y yd + (g - y0) f(s) + c_c                (Eqs. 1, 8)
    compliance     dy = K_c^-1 F = C F                                                 (Eq. 6)
    coupling       c_c = K_y dy                                                        (Eq. 9)
    modified goal  g_m = g + K_y^-1 (g - y0) f(s) + dy                                 (Eq. 11)
    as a PD law    tau ydd = K_y (g_m - y) - D_y yd                                    (Eq. 10)

y = [x, theta] (6,) is the tcp pose in the task (goal) frame, CONVENTIONS.md. K_y, D_y are
diagonal and given by their diagonals (..., 6). With tau in s and y in m / rad, K has units 1/s
and D is dimensionless; the unforced system oscillates at omega = sqrt(K / tau), so with
tau = 1 s, K = omega^2 numerically.

The movement's time scale: the fitted free-space movement is a minimum-jerk trajectory of
duration T (`DMPConfig.duration`), during which the phase decays from 1 to exp(-alpha_s T / tau)
(`DMPConfig.phase_span`). tau stays 1 s, so the learned gains keep their meaning (K = omega^2);
T = 2 s (not 1 s) slows the approach so that the peg meets the board gently: the minimum-jerk
profile of the 120-160 mm descent peaks at 1.9 x travel / T, and the first impact's force grows
with the speed (docs/design/compliance_loop.md, "The approach's duration"). The forcing weights w_i
are not learned: `fit_forcing_weights` fits them once, by locally weighted regression, for
the reference stiffness `k_ref`.

Change to the paper's literal form, where a skill asks for it (`DMPConfig.cruise` > 0): the
fitted movement cruises (`cruise_profile`). The paper designs f to give minimum-jerk movements;
the minimum-jerk speed peaks at mid-movement, where the 40-80 mm start height puts the board top
(33-50 % of the descent), so the peg meets the board at nearly the profile's peak. A profile
that spends the fraction c of the movement at a constant speed and blends in and out of it with
minimum-jerk steps (its acceleration continuous and zero at both ends) covers the same travel in
the same T at a peak speed of 2 / (1 + c) x travel / T instead of 1.875 x: at c = 0.5 the peg
meets the board 28 % slower (0.124 against 0.173 m/s for a 140 mm descent in 1.5 s, what the
minimum-jerk profile reaches in 2.1 s) and reaches the success depth 0.08 s later in free space
(what it changes at the touchdown: docs/design/contact_search.md). `cruise` = 0 is the paper's
minimum jerk.

Everything except the NumPy-only fitting and `rollout` is written over the array-API namespace
of the inputs and batched over leading dimensions; this module imports neither numpy nor jax.
"""

from __future__ import annotations

import dataclasses
import importlib
import math

from mjx_peg.array_api import namespace_of
from mjx_peg.errors import UsageError

WIDTH_PER_GAP = 0.3  # basis width sigma_i over the distance between neighbouring centres


@dataclasses.dataclass(frozen=True)
class DMPConfig:
    """The DMP's fixed (not learned) constants."""

    n_basis: int = 40  # Gaussian basis functions of the phase (20 per second of movement)
    alpha_s: float = 2.0  # phase decay rate: s(T) = exp(-alpha_s T / tau) = 0.018 at the end
    tau: float = 1.0  # s; time scale of Eqs. 1-2 (K = omega^2 at 1 s)
    k_ref: float = 300.0  # 1/s; stiffness at which the forcing is fitted (see fit_forcing_weights)
    duration: float = 2.0  # s; T, the duration of the fitted movement
    # c, the fraction of the movement at constant speed (`cruise_profile`); 0: minimum jerk
    cruise: float = 0.0

    def __post_init__(self):
        if not (isinstance(self.n_basis, int) and self.n_basis >= 2):
            raise UsageError(f"DMPConfig.n_basis must be an integer >= 2, got {self.n_basis!r}")
        for name in ("alpha_s", "tau", "k_ref", "duration"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise UsageError(f"DMPConfig.{name} must be a positive number, got {value!r}")
        if not (math.isfinite(self.cruise) and 0 <= self.cruise < 1):
            raise UsageError(f"DMPConfig.cruise must be in [0, 1), got {self.cruise!r}")

    @property
    def phase_span(self) -> float:
        """alpha_s T / tau: the phase decays from 1 to exp(-phase_span) over the movement."""
        return self.alpha_s * self.duration / self.tau


def phase(t, tau, alpha_s):
    """(...,) s(t) = exp(-alpha_s t / tau), solving tau ds/dt = -alpha_s s, s(0) = 1 (Eq. 2)."""
    xp = namespace_of(t)
    return xp.exp(-alpha_s * xp.asarray(t) / tau)


def basis_centers(n_basis: int, alpha_s: float, xp=None):
    """centers, widths (n_basis,): c_i = s(t_i) at times t_i evenly spaced over the movement
    (Eq. 4); `alpha_s` here is the phase's total decay over it, `DMPConfig.phase_span`.

    c_i = exp(-alpha_s i / (n_basis - 1)), from 1 down to exp(-alpha_s). sigma_i is
    WIDTH_PER_GAP (0.3) times the distance to the next (smaller) centre, the last one reusing its
    left neighbour's distance: neighbouring Gaussians cross at exp(-25/18) = 0.25 of their peak.
    Narrow bases keep the locally weighted regression accurate (its local fits ignore the
    neighbours' overlap; the widths and counts measured: docs/design/dmp_basis.md). Since the
    centres are spaced evenly in time the basis is denser in s where s is small, as the phase
    slows down.
    Returns arrays of `xp` (default NumPy, imported lazily).
    """
    xp = importlib.import_module("numpy") if xp is None else xp
    c = [math.exp(-alpha_s * i / (n_basis - 1)) for i in range(n_basis)]
    gaps = [c[i] - c[i + 1] for i in range(n_basis - 1)]
    widths = [WIDTH_PER_GAP * gap for gap in gaps + [gaps[-1]]]
    return xp.asarray(c, dtype=xp.float64), xp.asarray(widths, dtype=xp.float64)


def basis_widths(n_basis: int, alpha_s: float, xp=None):
    """(n_basis,) the widths sigma_i of `basis_centers` (the distance to the next centre)."""
    return basis_centers(n_basis, alpha_s, xp)[1]


def _basis_weights(s, centers, widths):
    """(..., n) normalized basis psi_i / sum_j psi_j at phase s (...,); safe for any s (Eq. 3)."""
    xp = namespace_of(s, centers, widths)
    e = -0.5 * ((s[..., None] - centers) / widths) ** 2
    # Normalize in the log domain: the ratio is unchanged and the denominator is >= 1.
    psi = xp.exp(e - xp.max(e, axis=-1, keepdims=True))
    return psi / xp.sum(psi, axis=-1, keepdims=True)


def forcing(s, weights, centers, widths):
    """(...,) f(s) = sum_i psi_i w_i / sum_i psi_i * s (Eq. 3); weights (n,) or (..., n).

    f is one scalar profile per batch element: it multiplies (g - y0) in all six dimensions.
    """
    xp = namespace_of(s, weights, centers, widths)
    s = xp.asarray(s)
    return xp.sum(_basis_weights(s, centers, widths) * weights, axis=-1) * s


def critical_damping(k, tau):
    """(..., 6) D = 2 sqrt(K tau): tau ydd + D yd + K y = 0 has a double root (no overshoot)."""
    xp = namespace_of(k)
    return 2.0 * xp.sqrt(k * tau)


def stiffness_diag(k_t, k_theta):
    """(..., 6) diagonal (k_t, k_t, k_t, k_theta, k_theta, k_theta) of K_y; k_t, k_theta (...,)."""
    xp = namespace_of(k_t, k_theta)
    k_t, k_theta = xp.broadcast_arrays(xp.asarray(k_t), xp.asarray(k_theta))
    return xp.stack([k_t, k_t, k_t, k_theta, k_theta, k_theta], axis=-1)


def compliance_offset(compliance, wrench):
    """(..., 6) dy = C F = K_c^-1 F (Eq. 6); compliance C (..., 6, 6), wrench F (..., 6)."""
    return (compliance @ wrench[..., None])[..., 0]


def coupling_term(k_y, compliance, wrench):
    """(..., 6) c_c = K_y C F (Eq. 9); k_y (..., 6) diagonal of K_y."""
    return k_y * compliance_offset(compliance, wrench)


def scaled_modified_goal(g, y0, f, k_ref: float, dy):
    """(..., 6) Eq. 11 with the fitted forcing scaled by K_y / k_ref: g + (g - y0) f / k_ref + dy.

    The paper fits f once while K_y is learned; unscaled, a stiffness far from the fitting one
    either ignores the forcing (K >> k_ref: the tcp jumps towards g at once) or is driven
    backwards by it (K << k_ref). Scaling f with K_y makes g_m the same for every learned
    stiffness, so the free-space movement keeps the fitted duration and only its tracking lag
    depends on K_y. Exactly Eq. 11 at K_y = k_ref.
    """
    return g + (g - y0) * f[..., None] / k_ref + dy


def dmp_acceleration(y, yd, g_m, k_y, d_y, tau):
    """(..., 6) ydd = tau^-1 (K_y (g_m - y) - D_y yd) (Eq. 10); k_y, d_y (..., 6) diagonals."""
    return (k_y * (g_m - y) - d_y * yd) / tau


def _smooth_step(x):
    """S(x) = 10 x^3 - 15 x^4 + 6 x^5 (the minimum-jerk step), S', S'' and the integral of S from
    0 to x."""
    return (x**3 * (10.0 - 15.0 * x + 6.0 * x * x), x**2 * (30.0 - 60.0 * x + 30.0 * x * x),
            x * (60.0 - 180.0 * x + 120.0 * x * x), x**4 * (2.5 - 3.0 * x + x * x))  # fmt: skip


def minimum_jerk(t, duration):
    """p, pd, pdd (...,): p = 10 r^3 - 15 r^4 + 6 r^5, r = clip(t / duration, 0, 1), and its rates.

    The normalized minimum-jerk profile: y(t) = y0 + (g - y0) p(t).
    """
    xp = namespace_of(t)
    p, dp, ddp, _ = _smooth_step(xp.clip(xp.asarray(t) / duration, 0.0, 1.0))
    return p, dp / duration, ddp / duration**2


def cruise_profile(t, duration, cruise):
    """p, pd, pdd (...,): the normalized movement that cruises (module docstring), y(t) = y0 +
    (g - y0) p(t); cruise c in (0, 1). With r = clip(t / T, 0, 1), b = (1 - c) / 2 the length of
    each blend and V = 1 / (1 - b) = 2 / (1 + c) the cruising speed (in travel / T):

        dp/dr = V S(r / b)          r < b          S the minimum-jerk step (`minimum_jerk`)
              = V                   b <= r <= 1 - b
              = V S((1 - r) / b)    r > 1 - b

    so p(0) = 0, p(1) = 1, and the speed and the acceleration are continuous, both zero at the
    ends."""
    xp = namespace_of(t)
    r = xp.clip(xp.asarray(t) / duration, 0.0, 1.0)
    b = (1.0 - cruise) / 2.0
    v = 1.0 / (1.0 - b)
    s_in, ds_in, _, int_in = _smooth_step(xp.clip(r / b, 0.0, 1.0))
    s_out, ds_out, _, int_out = _smooth_step(xp.clip((1.0 - r) / b, 0.0, 1.0))
    blend_in, blend_out = r < b, r > 1.0 - b
    p = xp.where(blend_in, v * b * int_in,
                 xp.where(blend_out, 1.0 - v * b * int_out, v * (r - b / 2.0)))  # fmt: skip
    pd = v * xp.where(blend_in, s_in, xp.where(blend_out, s_out, 1.0)) / duration
    pdd = (v / b) * xp.where(blend_in, ds_in, xp.where(blend_out, -ds_out, 0.0)) / duration**2
    return p, pd, pdd


def movement_profile(t, config: DMPConfig):
    """p, pd, pdd (...,) of the movement the forcing is fitted to: `minimum_jerk` over T, or
    `cruise_profile` where `config.cruise` > 0."""
    if config.cruise > 0:
        return cruise_profile(t, config.duration, config.cruise)
    return minimum_jerk(t, config.duration)


def fit_forcing_weights(config: DMPConfig):
    """(n_basis,) NumPy float64 weights w_i making the free-space DMP the movement of
    `movement_profile`: minimum jerk (the paper's), or the cruise where `config.cruise` > 0.

    Target: y(t) = y0 + (g - y0) p(t), T = duration, p the profile (minimum jerk: 10 r^3 - 15 r^4
    + 6 r^5, r = t / T). Inserting it in
    Eq. 8 with c_c = 0 and K = k_ref, D = 2 sqrt(k_ref tau), and dividing by (g - y0):

        f_target(t) = tau pdd - k_ref (1 - p) + D pd,

    the same scalar for all six dimensions, so one weight vector serves them all. f_target
    vanishes for t >= T (y = g at rest), so it is fitted on [0, 2T]. Locally weighted regression
    (Ijspeert et al. 2013, Eq. 2.14): with f = w_i s locally, w_i = sum_t psi_i s f_t / sum_t psi_i
    s^2, on 2001 samples; deterministic.

    At K = k_ref the free-space path is the profile up to the regression error (under 1 % of the
    travel with the defaults). The controller and `rollout` scale the forcing
    with K_y / k_ref (`scaled_modified_goal`), so the modified goal is the same for every learned
    stiffness: a stiffer K tracks it more tightly and runs slightly ahead of the profile, a
    softer one lags; both converge to g because f -> 0 with s. k_ref is the baseline stiffness.
    """
    np = importlib.import_module("numpy")
    tau, k, duration = config.tau, config.k_ref, config.duration
    d = 2.0 * math.sqrt(k * tau)
    t = np.linspace(0.0, 2.0 * duration, 2001)
    p, pd, pdd = movement_profile(t, config)
    f_target = tau * pdd - k * (1.0 - p) + d * pd
    s = phase(t, tau, config.alpha_s)
    centers, widths = basis_centers(config.n_basis, config.phase_span)
    psi = np.exp(-0.5 * ((s[:, None] - centers) / widths) ** 2)  # (n_t, n_basis)
    num = psi.T @ (s * f_target)
    den = psi.T @ (s * s)
    return num / den


def rollout(
    y0,
    g,
    k_y,
    config: DMPConfig,
    weights=None,
    compliance=None,
    wrench=None,
    duration: float | None = None,
    dt: float = 1e-3,
):
    """t (n,), y (n, 6), yd (n, 6): the DMP integrated (RK4, NumPy float64) from rest at y0.

    y0, g, k_y: (6,); weights (n_basis,) or None for f = 0; compliance (6, 6) and wrench (6,) a
    constant external wrench (None: free space); duration defaults to 1.5 times the movement.
    """
    np = importlib.import_module("numpy")
    y0, g, k_y = (np.asarray(a, dtype=np.float64) for a in (y0, g, k_y))
    tau = config.tau
    d_y = critical_damping(k_y, tau)
    centers, widths = basis_centers(config.n_basis, config.phase_span)
    w = np.zeros(config.n_basis) if weights is None else np.asarray(weights, dtype=np.float64)
    dy = np.zeros(6)
    if compliance is not None and wrench is not None:
        dy = compliance_offset(np.asarray(compliance, float), np.asarray(wrench, float))
    duration = max(3.0 * tau, 1.5 * config.duration) if duration is None else duration
    n = int(round(duration / dt)) + 1

    # The modified goal depends on time only: evaluate it once at every step and half step.
    t_half = 0.5 * dt * np.arange(2 * n + 1)
    f = forcing(phase(t_half, tau, config.alpha_s), w, centers, widths)
    g_m = scaled_modified_goal(g, y0, f, config.k_ref, dy)  # (2 n + 1, 6)

    def deriv(i, y, yd):
        return yd, dmp_acceleration(y, yd, g_m[i], k_y, d_y, tau)

    ys, yds = np.empty((n, 6)), np.empty((n, 6))
    y, yd = y0.copy(), np.zeros(6)
    for i in range(n):
        ys[i], yds[i] = y, yd
        k1 = deriv(2 * i, y, yd)
        k2 = deriv(2 * i + 1, y + dt / 2 * k1[0], yd + dt / 2 * k1[1])
        k3 = deriv(2 * i + 1, y + dt / 2 * k2[0], yd + dt / 2 * k2[1])
        k4 = deriv(2 * i + 2, y + dt * k3[0], yd + dt * k3[1])
        y = y + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        yd = yd + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return t_half[::2][:n], ys, yds


__all__ = [
    "DMPConfig",
    "WIDTH_PER_GAP",
    "basis_centers",
    "basis_widths",
    "compliance_offset",
    "coupling_term",
    "critical_damping",
    "dmp_acceleration",
    "cruise_profile",
    "fit_forcing_weights",
    "forcing",
    "minimum_jerk",
    "movement_profile",
    "phase",
    "rollout",
    "scaled_modified_goal",
    "stiffness_diag",
]
