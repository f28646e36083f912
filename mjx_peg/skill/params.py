"""The learned numbers: the 38 controller numbers (k_t, k_theta, the full 6x6 compliance
C = K_c^-1) and, where a skill learns them, the contact search's 9 constants.

The policy outputs an unbounded action in R^38; a map squashes it into a valid controller (paper
section 3.3: positive gains, compliance within physical ranges), for every input including +-1e6
(tanh saturates, nothing overflows). Two maps, both onto the ranges below:

- `controller_from_centred_action` (training's default): action 0 is a given
  centre (the baseline), and each number leaves it in both directions with the slope the
  sigmoid map has in the middle of its range, approaching the range's edges like tanh.
- `controller_from_action` (the sigmoid map): action 0 is the middle of each range; a centre
  near an edge sits where the sigmoid is flat (why the centred map exists:
  docs/design/baseline_tuning.md, "The action maps").

Order of the 38 numbers, in both the action and the physical vector:

    0       k_t       1/s         translational stiffness of K_y (tau ydd = K_y (g_m - y) - ...)
    1       k_theta   1/s         rotational stiffness of K_y
    2 + 6 i + j   C[i,j]          row-major compliance, dy = C F, y = [x (m), theta (rad)],
                                  F = [force (N), torque (N m)]:
                  C[i<3, j<3]    m/N         C[i<3, j>=3]   m/(N m)
                  C[i>=3, j<3]   rad/N       C[i>=3, j>=3]  rad/(N m)

Ranges (`DEFAULT_RANGES`), from the physics of a 50 mm peg in a hole with 0.75-2 mm clearance:

- k_t, k_theta in [10, 1000] 1/s, log-scaled. With tau = 1 s, K = omega^2: natural frequencies
  3.2-32 rad/s, settling times (critically damped, ~5/omega) of 1.6 s down to 0.16 s. Softer is
  too slow for a trial of a few seconds; stiffer approaches the limits of the 500 Hz loop
  (omega dt = 0.063 at 1000) and asks for torques beyond the wrist's 28 N m on centimetre
  errors. A log scale gives each decade equal room.
- translational compliance diagonal in [0, 2e-3] m/N: contact forces of 5-60 N then yield
  deflections up to 10-120 mm; the useful ones (~10 mm, several times the clearance) are reached
  at 5-10 N.
- rotational compliance diagonal in [0, 0.1] rad/(N m): contact torques of 0.5-5 N m then yield
  up to 0.05-0.5 rad, covering the ~0.2 rad (12 deg) grasp tilts of the paper.
- Diagonal entries stay >= 0: positive compliance yields to the contact; a negative one would
  push into it (positive feedback on the contact force).
- Off-diagonal entries in +-OFF_DIAGONAL_FRACTION (0.5) * sqrt(Cmax_ii Cmax_jj): the geometric
  mean has the entry's units (1/N for the force-torque cross terms, with rad dimensionless), and
  a coupling at half of it keeps the symmetric part of any 2x2 block with maximal diagonals
  positive definite, so it cannot dominate the direct compliance; this gives 1e-3 m/N within the
  translational block, 0.05 rad/(N m) within the rotational one and 7.1e-3 between them (a
  10 N lateral force may tilt the peg by up to 0.07 rad, a 1 N m torque shift it by 7 mm).
  C is not symmetric in general (the paper learns the full K_c); a non-symmetric compliance is
  not conservative, which the learning is free to exploit or avoid.

The contact search's constants (skill/search.py, `search.LEARNED`), where a policy learns them,
follow the 38 in the same vector (47 numbers): the spiral's pitch p, radius R and speed v, the
axial compliance's factor while spiralling kappa, the alignment's rate k_a and depth d_a, the
insertion press's depth d_i and factor kappa_i, the movement's duration T. Their ranges
(`SEARCH_RANGES`) are physical, not drawn around the hand-tuned skill:

- p in [1, 25] mm (log): from below the 12 mm peg's capture width (2 sqrt(R_h^2 - R_p^2) =
  3 mm) to the 50 mm peg's (12 mm) twice over;
- R in [5, 50] mm (log): the localization errors' range (up to 8 mm in the paper's grids) and
  the tip's drift, to six times that;
- v in [5, 100] mm/s (log): a turn of a 25 mm spiral in 31 down to 1.6 s;
- kappa in [0.5, 4] (log): the press while spiralling between twice and a quarter of C_zz's
  (with `SkillConfig.spiral_axial_ref` c_r > 0: a compliance of its own, kappa c_r);
- k_a in [0.1, 10] rad/(N m s) (log): the alignment following a 1 N m moment by 0.1 to 10 rad/s;
- d_a in [0, 40] mm and d_i in [10, 70] mm below the hole's estimated entrance (linear): the
  80 mm hole's depth, from its entrance to 10 mm above its exit;
- kappa_i in [0.2, 1] (log): the press deep in the hole up to five times C_zz's stiffness;
- T in [0.8, 3] s (log): the approach's movement.

The compliance loop's gain scales with the axial compliance's factor; over these ranges
(kappa up to 4 times the largest C_zz) it stays below the stable limit (skill/control_step.py,
tests/skill/test_stability.py).

Written over the array-API namespace of the inputs (NumPy or JAX, batched over `...`); imports
neither numpy nor jax at module level.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from typing import NamedTuple

from mjx_peg.array_api import namespace_of
from mjx_peg.errors import UsageError
from mjx_peg.skill.search import LEARNED, SearchValues

N_PARAMS = 38  # the controller's numbers
N_SEARCH = len(LEARNED)  # the contact search's learnable constants
N_LEARNED = N_PARAMS + N_SEARCH  # a policy that learns both
OFF_DIAGONAL_FRACTION = 0.5
# (low, high, log-scaled) of each learnable constant of the contact search (module docstring)
SEARCH_RANGES: dict[str, tuple[float, float, bool]] = {
    "spiral_pitch": (0.001, 0.025, True),
    "spiral_radius": (0.005, 0.05, True),
    "spiral_speed": (0.005, 0.1, True),
    "spiral_axial": (0.5, 4.0, True),
    "align_rate": (0.1, 10.0, True),
    "align_depth": (0.0, 0.04, False),
    "insert_depth": (0.01, 0.07, False),
    "insert_axial": (0.2, 1.0, True),
    "movement_s": (0.8, 3.0, True),
}

PARAM_NAMES: tuple[str, ...] = ("k_t", "k_theta") + tuple(
    f"C[{i},{j}]" for i in range(6) for j in range(6)
)
LEARNED_NAMES: tuple[str, ...] = PARAM_NAMES + LEARNED


def _compliance_unit(i: int, j: int) -> str:
    return ("m" if i < 3 else "rad") + "/" + ("N" if j < 3 else "(N m)")


PARAM_UNITS: tuple[str, ...] = ("1/s", "1/s") + tuple(
    _compliance_unit(i, j) for i in range(6) for j in range(6)
)
LEARNED_UNITS: tuple[str, ...] = PARAM_UNITS + ("m", "m", "m/s", "1", "rad/(N m s)", "m", "m", "1",
                                                "s")  # fmt: skip


class ControllerParams(NamedTuple):
    """The 38 physical controller numbers and, where learned, the contact search's constants (a
    JAX pytree); leading dims `...` shared."""

    k_t: object  # (...,) translational stiffness of K_y, 1/s
    k_theta: object  # (...,) rotational stiffness of K_y, 1/s
    compliance: object  # (..., 6, 6) C = K_c^-1, dy = C F (units in the module docstring)
    search: SearchValues | None = None  # (...,) each; None: the skill config's constants


@dataclasses.dataclass(frozen=True)
class ParamRanges:
    """Physical ranges of the 38 numbers (justified in the module docstring)."""

    k_t: tuple[float, float] = (10.0, 1000.0)  # 1/s, log-scaled
    k_theta: tuple[float, float] = (10.0, 1000.0)  # 1/s, log-scaled
    trans_compliance_max: float = 2e-3  # m/N, diagonal C[i, i], i < 3, in [0, max]
    rot_compliance_max: float = 0.1  # rad/(N m), diagonal C[i, i], i >= 3, in [0, max]
    off_diagonal_fraction: float = OFF_DIAGONAL_FRACTION  # |C[i,j]| <= frac sqrt(max_i max_j)

    def __post_init__(self):
        for name in ("k_t", "k_theta"):
            lo, hi = getattr(self, name)
            if not (0 < lo < hi and math.isfinite(hi)):
                raise UsageError(f"ParamRanges.{name} must satisfy 0 < low < high, got {lo, hi}")
        for name in ("trans_compliance_max", "rot_compliance_max", "off_diagonal_fraction"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise UsageError(f"ParamRanges.{name} must be a positive number, got {value!r}")

    def compliance_bound(self) -> tuple[tuple[float, ...], ...]:
        """6x6 bound b: C[i,i] in [0, b[i][i]], C[i,j] in [-b[i][j], b[i][j]] for i != j."""
        diag = (self.trans_compliance_max,) * 3 + (self.rot_compliance_max,) * 3
        return tuple(
            tuple(
                diag[i] if i == j else self.off_diagonal_fraction * math.sqrt(diag[i] * diag[j])
                for j in range(6)
            )
            for i in range(6)
        )


DEFAULT_RANGES = ParamRanges()

_DIAGONAL = tuple(tuple(float(i == j) for j in range(6)) for i in range(6))


def _sigmoid(a, xp):
    """(...) 1 / (1 + exp(-a)) written as (1 + tanh(a / 2)) / 2: no overflow for any a."""
    return 0.5 + 0.5 * xp.tanh(0.5 * a)


def _inverse_tanh(u, xp):
    """(...) atanh(u) with u clipped to the open interval (-1, 1) of the dtype: finite."""
    edge = 1.0 - 4.0 * xp.finfo(u.dtype).eps
    u = xp.clip(u, -edge, edge)
    return 0.5 * xp.log((1.0 + u) / (1.0 - u))


def _split_action(action, xp):
    """(...,), (...,), (..., 6, 6) parts of a (..., 38) or (..., 47) vector, and its (..., 9)
    search part (None for 38)."""
    if action.shape[-1] not in (N_PARAMS, N_LEARNED):
        raise UsageError(
            f"expected a last axis of {N_PARAMS} or {N_LEARNED}, got shape {tuple(action.shape)}"
        )
    shape = tuple(action.shape[:-1])
    compliance = xp.reshape(action[..., 2:N_PARAMS], shape + (6, 6))
    search = action[..., N_PARAMS:] if action.shape[-1] == N_LEARNED else None
    return action[..., 0], action[..., 1], compliance, search


def _search_scales(xp, dtype):
    """low and high ends (9,) of the search constants' ranges (logs where log-scaled), and the
    log-scaled mask (9,)."""
    ranges = [SEARCH_RANGES[name] for name in LEARNED]
    logged = xp.asarray([log for _, _, log in ranges])
    lo = xp.asarray([math.log(a) if g else a for a, _, g in ranges], dtype=dtype)
    hi = xp.asarray([math.log(b) if g else b for _, b, g in ranges], dtype=dtype)
    return lo, hi, logged


def _search_to_unit(values, xp):
    """(..., 9) position of each search constant in its range, 0 low, 1 high."""
    lo, hi, logged = _search_scales(xp, values.dtype)
    x = xp.where(logged, xp.log(xp.where(logged, values, 1.0)), values)
    return (x - lo) / (hi - lo)


def _search_from_unit(u, xp):
    """(..., 9) search constants at unit positions u (the inverse of `_search_to_unit`)."""
    lo, hi, logged = _search_scales(xp, u.dtype)
    x = lo + (hi - lo) * u
    low = xp.asarray([SEARCH_RANGES[n][0] for n in LEARNED], dtype=u.dtype)
    high = xp.asarray([SEARCH_RANGES[n][1] for n in LEARNED], dtype=u.dtype)
    return xp.clip(xp.where(logged, xp.exp(x), x), low, high)  # clip: rounding only


def search_from_vector(vector) -> SearchValues:
    """SearchValues of a (..., 9) vector in `search.LEARNED` order."""
    return SearchValues(*(vector[..., i] for i in range(N_SEARCH)))


def vector_from_search(values: SearchValues):
    """(..., 9) vector of SearchValues in `search.LEARNED` order (the learned fields alone)."""
    learned = [getattr(values, name) for name in LEARNED]
    return namespace_of(*learned).stack(learned, axis=-1)


def controller_from_action(action, ranges: ParamRanges = DEFAULT_RANGES) -> ControllerParams:
    """ControllerParams from an unbounded action (..., 38); every finite action is valid.

    k = exp(log lo + (log hi - log lo) sigmoid(a)) in [lo, hi];
    C[i,i] = b_ii sigmoid(a) in [0, b_ii]; C[i,j] = b_ij tanh(a) in [-b_ij, b_ij]; a search
    constant at sigmoid(a) of its range (log-scaled where `SEARCH_RANGES` says).
    """
    xp = namespace_of(action)
    a_kt, a_kth, a_c, a_s = _split_action(action, xp)

    def log_scaled(a, bounds):
        lo, hi = math.log(bounds[0]), math.log(bounds[1])
        # The clip only removes rounding (exp(log 1000) > 1000 in float32).
        return xp.clip(xp.exp(lo + (hi - lo) * _sigmoid(a, xp)), bounds[0], bounds[1])

    bound = xp.asarray(ranges.compliance_bound(), dtype=action.dtype)
    diagonal = xp.asarray(_DIAGONAL, dtype=action.dtype) > 0.5
    compliance = bound * xp.where(diagonal, _sigmoid(a_c, xp), xp.tanh(a_c))
    search = None if a_s is None else search_from_vector(_search_from_unit(_sigmoid(a_s, xp), xp))
    return ControllerParams(
        log_scaled(a_kt, ranges.k_t), log_scaled(a_kth, ranges.k_theta), compliance, search
    )


def _unit_weight(xp, dtype, size: int = N_PARAMS):
    """(size,) w: the sigmoid map is u = sigmoid(w a) for every number (w = 2 on the couplings,
    whose tanh(a) = 2 sigmoid(2 a) - 1), so its slope du/da at its middle is w / 4."""
    w = [1.0, 1.0] + [1.0 if i == j else 2.0 for i in range(6) for j in range(6)]
    return xp.asarray(w + [1.0] * (size - N_PARAMS), dtype=dtype)


def _unit_scales(ranges: ParamRanges, xp, dtype):
    """log k low and high ends (2,), compliance bound (36,) and diagonal mask (36,)."""
    lo = xp.asarray([math.log(ranges.k_t[0]), math.log(ranges.k_theta[0])], dtype=dtype)
    hi = xp.asarray([math.log(ranges.k_t[1]), math.log(ranges.k_theta[1])], dtype=dtype)
    bound = xp.reshape(xp.asarray(ranges.compliance_bound(), dtype=dtype), (36,))
    diagonal = xp.reshape(xp.asarray(_DIAGONAL, dtype=dtype), (36,)) > 0.5
    return lo, hi, bound, diagonal


def _to_unit(vector, ranges: ParamRanges, xp):
    """(..., 38) position of each number in its range, 0 at the low end and 1 at the high end
    (log-scaled for k_t, k_theta; C[i,j] = b_ij (2 u - 1) off the diagonal)."""
    lo, hi, bound, diagonal = _unit_scales(ranges, xp, vector.dtype)
    u_k = (xp.log(vector[..., :2]) - lo) / (hi - lo)
    v = vector[..., 2:N_PARAMS] / bound
    parts = [u_k, xp.where(diagonal, v, 0.5 * (v + 1.0))]
    if vector.shape[-1] == N_LEARNED:
        parts.append(_search_to_unit(vector[..., N_PARAMS:], xp))
    return xp.concat(parts, axis=-1)


def _from_unit(u, ranges: ParamRanges, xp):
    """(..., 38) physical vector of unit positions u (the inverse of `_to_unit`)."""
    lo, hi, bound, diagonal = _unit_scales(ranges, xp, u.dtype)
    k_lo = xp.asarray([ranges.k_t[0], ranges.k_theta[0]], dtype=u.dtype)
    k_hi = xp.asarray([ranges.k_t[1], ranges.k_theta[1]], dtype=u.dtype)
    k = xp.clip(xp.exp(lo + (hi - lo) * u[..., :2]), k_lo, k_hi)  # clip: rounding only
    c = bound * xp.where(diagonal, u[..., 2:N_PARAMS], 2.0 * u[..., 2:N_PARAMS] - 1.0)
    parts = [k, c]
    if u.shape[-1] == N_LEARNED:
        parts.append(_search_from_unit(u[..., N_PARAMS:], xp))
    return xp.concat(parts, axis=-1)


def _centred_frame(centre, ranges: ParamRanges, xp, dtype):
    """The centre's unit position u0 (38,) or (47,) and the map's slope s at it (same)."""
    u0 = _to_unit(xp.asarray(centre, dtype=dtype), ranges, xp)
    return u0, 0.25 * _unit_weight(xp, dtype, u0.shape[-1])


def check_centre(centre, ranges: ParamRanges = DEFAULT_RANGES):
    """The (38,) float64 NumPy centre of a centred map; ValueError unless strictly inside the
    ranges (on an edge the map could not leave it on that side)."""
    np = importlib.import_module("numpy")
    centre = np.asarray(centre, dtype=np.float64)
    if centre.shape not in ((N_PARAMS,), (N_LEARNED,)) or not np.all(np.isfinite(centre)):
        raise UsageError(f"the map's centre must be {N_PARAMS} or {N_LEARNED} finite numbers")
    if np.any(centre[:2] <= 0):
        raise UsageError("the map's centre has a stiffness <= 0")
    u = _to_unit(centre, ranges, np)
    if not np.all((u > 0) & (u < 1)):
        names = [LEARNED_NAMES[i] for i in np.flatnonzero(~((u > 0) & (u < 1)))]
        raise UsageError(f"the map's centre is not strictly inside the ranges at {names}")
    return centre


def controller_from_centred_action(action, centre, ranges: ParamRanges = DEFAULT_RANGES):
    """ControllerParams from an unbounded action (..., 38) under the centred map.

    Action 0 is the physical vector `centre` (38,) (the baseline, for training), and there each
    number moves with the slope of the sigmoid map at its middle (du/da = w / 4, u the position
    in the range, `_unit_weight`) in both directions, approaching the range's edges like tanh:
    u = u0 + (1 - u0) tanh(s a / (1 - u0)) for a >= 0, u0 + u0 tanh(s a / u0) for a < 0.
    The sigmoid map puts the centre of its sensitivity in the middle of each range; a prior near
    an edge (k = 900 of [10, 1000] sits at sigmoid 0.977) then moves ~20 times less for the same
    exploration, and PPO started there barely moves it (docs/design/credible_contact.md).
    """
    xp = namespace_of(action)
    _split_action(action, xp)  # checks the last axis (38)
    u0, s = _centred_frame(centre, ranges, xp, action.dtype)
    if u0.shape[-1] != action.shape[-1]:
        raise UsageError(f"a centre of {u0.shape[-1]} numbers for actions of {action.shape[-1]}")
    up, down = 1.0 - u0, u0
    u = u0 + xp.where(action >= 0, up * xp.tanh(s * action / up), down * xp.tanh(s * action / down))
    return controller_from_vector(_from_unit(u, ranges, xp))


def centred_action_from_controller(
    params: ControllerParams, centre, ranges: ParamRanges = DEFAULT_RANGES
):
    """(..., 38) action whose `controller_from_centred_action` is `params` (values inside the
    ranges; the edges map to a large finite action)."""
    vector = vector_from_controller(params)
    xp = namespace_of(vector)
    u0, s = _centred_frame(centre, ranges, xp, vector.dtype)
    u = _to_unit(vector, ranges, xp)
    up, down = 1.0 - u0, u0
    d = u - u0
    return xp.where(
        d >= 0, up / s * _inverse_tanh(d / up, xp), down / s * _inverse_tanh(d / down, xp)
    )


def action_from_controller(params: ControllerParams, ranges: ParamRanges = DEFAULT_RANGES):
    """(..., 38) action whose `controller_from_action` is `params` (values clipped to the ranges).

    Values on a range's edge map to a large finite action (about +-35 in float64, +-15 in
    float32) rather than infinity.
    """
    xp = namespace_of(params.k_t, params.k_theta, params.compliance)
    dtype = params.compliance.dtype

    def inverse_log_scaled(k, bounds):
        lo, hi = math.log(bounds[0]), math.log(bounds[1])
        u = (xp.log(xp.asarray(k, dtype=dtype)) - lo) / (hi - lo)
        return 2.0 * _inverse_tanh(2.0 * u - 1.0, xp)

    bound = xp.asarray(ranges.compliance_bound(), dtype=dtype)
    diagonal = xp.asarray(_DIAGONAL, dtype=dtype) > 0.5
    u = params.compliance / bound
    a_c = xp.where(diagonal, 2.0 * _inverse_tanh(2.0 * u - 1.0, xp), _inverse_tanh(u, xp))
    search = None
    if params.search is not None:
        u_s = _search_to_unit(vector_from_search(params.search), xp)
        search = search_from_vector(2.0 * _inverse_tanh(2.0 * u_s - 1.0, xp))
    return vector_from_controller(
        ControllerParams(
            inverse_log_scaled(params.k_t, ranges.k_t),
            inverse_log_scaled(params.k_theta, ranges.k_theta),
            a_c,
            search,
        )
    )


def vector_from_controller(params: ControllerParams):
    """(..., 38) physical vector [k_t, k_theta, C row-major], then (..., 47) with the search's
    constants where it has them (for export and logging)."""
    xp = namespace_of(params.k_t, params.k_theta, params.compliance)
    c = params.compliance
    shape = tuple(c.shape[:-2])
    k_t = xp.broadcast_to(xp.asarray(params.k_t, dtype=c.dtype), shape)
    k_theta = xp.broadcast_to(xp.asarray(params.k_theta, dtype=c.dtype), shape)
    parts = [k_t[..., None], k_theta[..., None], xp.reshape(c, shape + (36,))]
    if params.search is not None:
        search = xp.asarray(vector_from_search(params.search), dtype=c.dtype)
        parts.append(xp.broadcast_to(search, shape + (N_SEARCH,)))
    return xp.concat(parts, axis=-1)


def controller_from_vector(vector) -> ControllerParams:
    """ControllerParams from a physical (..., 38) or (..., 47) vector (the inverse of
    vector_from_controller)."""
    xp = namespace_of(vector)
    k_t, k_theta, compliance, search = _split_action(vector, xp)
    return ControllerParams(
        k_t, k_theta, compliance, None if search is None else search_from_vector(search)
    )


def stiffness_from_compliance(compliance, max_condition: float = 1e12):
    """(..., 6, 6) NumPy K_c = C^-1 for reporting; raises ValueError where C is not invertible.

    NumPy boundary function (not traced): the controller never needs K_c, it uses dy = C F. A
    compliance with an entire zero row or column (an infinitely stiff direction, e.g. a diagonal
    entry squashed to 0 with its couplings) or a condition number above `max_condition` has no
    meaningful finite K_c, and this raises instead of returning inf or NaN.
    """
    np = importlib.import_module("numpy")
    c = np.asarray(compliance, dtype=np.float64)
    if c.shape[-2:] != (6, 6):
        raise UsageError(f"compliance must have shape (..., 6, 6), got {c.shape}")
    if not np.all(np.isfinite(c)):
        raise UsageError("compliance has NaN or infinite entries")
    cond = np.linalg.cond(c) if c.size else np.zeros(c.shape[:-2])
    if np.any(~np.isfinite(cond) | (cond > max_condition)):
        raise UsageError(
            f"compliance is singular (condition number {np.max(cond):.3g} > {max_condition:.3g}):"
            " an infinitely stiff direction has no finite K_c"
        )
    return np.linalg.inv(c)


__all__ = [
    "DEFAULT_RANGES",
    "LEARNED_NAMES",
    "LEARNED_UNITS",
    "N_LEARNED",
    "N_PARAMS",
    "N_SEARCH",
    "OFF_DIAGONAL_FRACTION",
    "PARAM_NAMES",
    "PARAM_UNITS",
    "SEARCH_RANGES",
    "ControllerParams",
    "ParamRanges",
    "action_from_controller",
    "centred_action_from_controller",
    "check_centre",
    "controller_from_centred_action",
    "controller_from_action",
    "controller_from_vector",
    "search_from_vector",
    "stiffness_from_compliance",
    "vector_from_controller",
    "vector_from_search",
]
