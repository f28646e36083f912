"""The 38 learned controller numbers: k_t, k_theta and the full 6x6 compliance C = K_c^-1.

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

N_PARAMS = 38
OFF_DIAGONAL_FRACTION = 0.5

PARAM_NAMES: tuple[str, ...] = ("k_t", "k_theta") + tuple(
    f"C[{i},{j}]" for i in range(6) for j in range(6)
)


def _compliance_unit(i: int, j: int) -> str:
    return ("m" if i < 3 else "rad") + "/" + ("N" if j < 3 else "(N m)")


PARAM_UNITS: tuple[str, ...] = ("1/s", "1/s") + tuple(
    _compliance_unit(i, j) for i in range(6) for j in range(6)
)


class ControllerParams(NamedTuple):
    """The 38 physical controller numbers (a JAX pytree); leading dims `...` shared."""

    k_t: object  # (...,) translational stiffness of K_y, 1/s
    k_theta: object  # (...,) rotational stiffness of K_y, 1/s
    compliance: object  # (..., 6, 6) C = K_c^-1, dy = C F (units in the module docstring)


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
    """(...,), (...,), (..., 6, 6) parts of a (..., 38) vector."""
    if action.shape[-1] != N_PARAMS:
        raise UsageError(f"expected a last axis of {N_PARAMS}, got shape {tuple(action.shape)}")
    shape = tuple(action.shape[:-1])
    return action[..., 0], action[..., 1], xp.reshape(action[..., 2:], shape + (6, 6))


def controller_from_action(action, ranges: ParamRanges = DEFAULT_RANGES) -> ControllerParams:
    """ControllerParams from an unbounded action (..., 38); every finite action is valid.

    k = exp(log lo + (log hi - log lo) sigmoid(a)) in [lo, hi];
    C[i,i] = b_ii sigmoid(a) in [0, b_ii]; C[i,j] = b_ij tanh(a) in [-b_ij, b_ij].
    """
    xp = namespace_of(action)
    a_kt, a_kth, a_c = _split_action(action, xp)

    def log_scaled(a, bounds):
        lo, hi = math.log(bounds[0]), math.log(bounds[1])
        # The clip only removes rounding (exp(log 1000) > 1000 in float32).
        return xp.clip(xp.exp(lo + (hi - lo) * _sigmoid(a, xp)), bounds[0], bounds[1])

    bound = xp.asarray(ranges.compliance_bound(), dtype=action.dtype)
    diagonal = xp.asarray(_DIAGONAL, dtype=action.dtype) > 0.5
    compliance = bound * xp.where(diagonal, _sigmoid(a_c, xp), xp.tanh(a_c))
    return ControllerParams(
        log_scaled(a_kt, ranges.k_t), log_scaled(a_kth, ranges.k_theta), compliance
    )


def _unit_weight(xp, dtype):
    """(38,) w: the sigmoid map is u = sigmoid(w a) for every number (w = 2 on the couplings,
    whose tanh(a) = 2 sigmoid(2 a) - 1), so its slope du/da at its middle is w / 4."""
    return xp.asarray([1.0, 1.0] + [1.0 if i == j else 2.0 for i in range(6) for j in range(6)],
                      dtype=dtype)  # fmt: skip


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
    v = vector[..., 2:] / bound
    return xp.concat([u_k, xp.where(diagonal, v, 0.5 * (v + 1.0))], axis=-1)


def _from_unit(u, ranges: ParamRanges, xp):
    """(..., 38) physical vector of unit positions u (the inverse of `_to_unit`)."""
    lo, hi, bound, diagonal = _unit_scales(ranges, xp, u.dtype)
    k_lo = xp.asarray([ranges.k_t[0], ranges.k_theta[0]], dtype=u.dtype)
    k_hi = xp.asarray([ranges.k_t[1], ranges.k_theta[1]], dtype=u.dtype)
    k = xp.clip(xp.exp(lo + (hi - lo) * u[..., :2]), k_lo, k_hi)  # clip: rounding only
    c = bound * xp.where(diagonal, u[..., 2:], 2.0 * u[..., 2:] - 1.0)
    return xp.concat([k, c], axis=-1)


def _centred_frame(centre, ranges: ParamRanges, xp, dtype):
    """The centre's unit position u0 (38,) and the map's slope s at it (38,)."""
    return _to_unit(xp.asarray(centre, dtype=dtype), ranges, xp), 0.25 * _unit_weight(xp, dtype)


def check_centre(centre, ranges: ParamRanges = DEFAULT_RANGES):
    """The (38,) float64 NumPy centre of a centred map; ValueError unless strictly inside the
    ranges (on an edge the map could not leave it on that side)."""
    np = importlib.import_module("numpy")
    centre = np.asarray(centre, dtype=np.float64)
    if centre.shape != (N_PARAMS,) or not np.all(np.isfinite(centre)):
        raise UsageError(f"the map's centre must be {N_PARAMS} finite numbers")
    if np.any(centre[:2] <= 0):
        raise UsageError("the map's centre has a stiffness <= 0")
    u = _to_unit(centre, ranges, np)
    if not np.all((u > 0) & (u < 1)):
        names = [PARAM_NAMES[i] for i in np.flatnonzero(~((u > 0) & (u < 1)))]
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
    return vector_from_controller(
        ControllerParams(
            inverse_log_scaled(params.k_t, ranges.k_t),
            inverse_log_scaled(params.k_theta, ranges.k_theta),
            a_c,
        )
    )


def vector_from_controller(params: ControllerParams):
    """(..., 38) physical vector [k_t, k_theta, C row-major] (for export and logging)."""
    xp = namespace_of(params.k_t, params.k_theta, params.compliance)
    c = params.compliance
    shape = tuple(c.shape[:-2])
    k_t = xp.broadcast_to(xp.asarray(params.k_t, dtype=c.dtype), shape)
    k_theta = xp.broadcast_to(xp.asarray(params.k_theta, dtype=c.dtype), shape)
    return xp.concat([k_t[..., None], k_theta[..., None], xp.reshape(c, shape + (36,))], axis=-1)


def controller_from_vector(vector) -> ControllerParams:
    """ControllerParams from a physical (..., 38) vector (the inverse of vector_from_controller)."""
    xp = namespace_of(vector)
    return ControllerParams(*_split_action(vector, xp))


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
    "N_PARAMS",
    "OFF_DIAGONAL_FRACTION",
    "PARAM_NAMES",
    "PARAM_UNITS",
    "ControllerParams",
    "ParamRanges",
    "action_from_controller",
    "centred_action_from_controller",
    "check_centre",
    "controller_from_centred_action",
    "controller_from_action",
    "controller_from_vector",
    "stiffness_from_compliance",
    "vector_from_controller",
]
