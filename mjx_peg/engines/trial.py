"""One insertion trial, defined once for both engines.

A trial: the board, peg and errors of one `TrialSpec`, the compliant DMP with the trial's 38
controller parameters driving the operational-space torque controller at 500 Hz (2 ms physics),
until the peg tip has passed the hole and is within `success_height` of the table, or until the
time limit. This module holds what defines a trial (its config, the success test, the reward,
the settle test, the result); `engines/period.py` composes them into the control period both
engines (`engines/lanes.py`, `engines/mjx.py`) call, so their outcomes can only differ through
the physics.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import NamedTuple

import numpy as np

from mjx_peg.array_api import namespace_of
from mjx_peg.errors import UsageError
from mjx_peg.skill import dmp, sensor
from mjx_peg.skill.control_step import Basis, ControlConfig
from mjx_peg.skill.params import (
    N_LEARNED,
    N_PARAMS,
    SEARCH_RANGES,
    ControllerParams,
    controller_from_vector,
)
from mjx_peg.skill.search import SkillConfig
from mjx_peg.world.constants import SUCCESS_REWARD, TORQUE_LIMITS


@dataclasses.dataclass(frozen=True)
class RewardConfig:
    """Reward of one trial: `success` on success, else up to `shaped` by the tip's progress."""

    success: float = SUCCESS_REWARD
    shaped: float = 10000.0  # a failed trial earns shaped * (1 - d_end / d_start), clipped at 0


@dataclasses.dataclass(frozen=True)
class TrialConfig:
    """Everything about a trial that is not drawn per trial."""

    time_limit_s: float = 60.0  # the paper's evaluation limit; training may use less
    timestep: float = 0.002  # physics and control period (500 Hz), must match the scene
    success_height: float = 0.02  # success: tip within this height of the table (m)
    dmp: dmp.DMPConfig = dataclasses.field(default_factory=dmp.DMPConfig)
    pinv_damping: float = 0.01  # damping of J+ near singularities
    # rad/s. Faster counts as a numerical failure (`unstable`): twice the UR5e's 180 deg/s joint
    # limit, where the real arm would protective-stop. Baseline trials stay under 3 rad/s;
    # chattering or diverging controllers exceed it long before the physics returns NaN.
    max_joint_speed: float = 2.0 * math.pi
    reward: RewardConfig = dataclasses.field(default_factory=RewardConfig)
    # The F/T sensor as the controller sees it (skill/sensor.py: the UR5e's built-in sensor).
    sensor: sensor.SensorConfig = dataclasses.field(default_factory=sensor.SensorConfig)
    # N. Protective stop: a sensed tool force beyond it ends the trial as a failure
    # (`protective_stop`). The UR5e's default tool-force limit: "a protective stop if the robot
    # hits something. This stop force limit is lower than 150 N" (UR5 user manual, safety);
    # e-Series "Force Limit" safety function, tolerance 25 N (UR5e user manual, 3. Safety-related
    # Functions and Interfaces); configurable in PolyScope's Safety > Robot Limits.
    max_tool_force: float = 150.0
    # s. Time constant T_c of the compliance damping D_c = T_c K_c (Eq. 4): the coupling sees the
    # sensed wrench through a first-order low-pass of this time constant, long enough that no
    # learnable vector can make the compliance loop oscillate (the analysis in
    # skill/control_step.py: loop gains up to 190, latency up to 2 periods, 25-100 Hz filters).
    coupling_time_constant: float = 0.75
    # N, N m: dead bands of the wrench the compliance acts on (control_step.deadband); 0: the
    # paper's coupling
    force_deadband: float = 0.0
    moment_deadband: float = 0.0
    # How the skill frees a peg resting on the board top (skill/search.py, an extension); the
    # default, all off: the paper's skill. `skill.search.SKILLS` names the presets.
    search: SkillConfig = dataclasses.field(default_factory=SkillConfig)
    chatter_window_s: float = 1.0  # s: the chatter metric averages the last window of a trial
    # A failure whose outcome can no longer change ends at once, flagged `settled` (see
    # `settle_update`): after settle_after_s (the DMP's forcing is over), the envelope (least and
    # greatest value) of the tcp position, the wrench the compliance sees (after the F/T pipeline
    # and the damping's low-pass: a filtered wrench still moving is not settled) and the fastest
    # joint speed over a window of settle_window_s has matched the previous window's within
    # settle_tip_m, settle_force_n, settle_moment_nm and settle_joint_speed, settle_windows times
    # in a row: the arm is at rest, or repeats the same oscillation (a peg chattering on the board
    # top); or a settle window after the search withdrew the peg (`search.search_withdrawn`).
    # end_settled=False runs every failure to the time limit, the paper's protocol.
    end_settled: bool = True
    # s: twice the DMP's 2 s movement (dmp.DMPConfig.duration); the phase is then
    # exp(-alpha_s 4 / tau) = 3e-4 at the defaults
    settle_after_s: float = 4.0
    settle_window_s: float = 1.0
    settle_windows: int = 1
    settle_tip_m: float = 1e-5
    settle_force_n: float = 0.5
    settle_moment_nm: float = 0.05
    settle_joint_speed: float = 0.05  # rad/s

    def __post_init__(self):
        positive = ("time_limit_s", "timestep", "success_height", "max_joint_speed",
                    "settle_window_s", "settle_joint_speed", "settle_tip_m", "settle_force_n",
                    "settle_moment_nm", "max_tool_force", "chatter_window_s")  # fmt: skip
        if not (math.isfinite(self.settle_after_s) and self.settle_after_s >= 0):
            raise UsageError(
                f"TrialConfig.settle_after_s must be a number >= 0, got {self.settle_after_s!r}"
            )
        if isinstance(self.settle_windows, bool) or not (
            isinstance(self.settle_windows, int) and self.settle_windows >= 1
        ):
            raise UsageError(
                f"TrialConfig.settle_windows must be an integer >= 1, got {self.settle_windows!r}"
            )
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise UsageError(f"TrialConfig.{name} must be a positive number, got {value!r}")
        value = self.coupling_time_constant
        if not (math.isfinite(value) and value >= 0):
            raise UsageError(
                f"TrialConfig.coupling_time_constant must be a number >= 0, got {value!r}"
            )
        if self.time_limit_s < self.timestep:
            raise UsageError(
                f"TrialConfig.time_limit_s ({self.time_limit_s}) is shorter than one step"
            )

    @property
    def max_steps(self) -> int:
        return int(round(self.time_limit_s / self.timestep))

    @property
    def chatter_steps(self) -> int:
        """Control periods in the chatter window."""
        return max(1, int(round(self.chatter_window_s / self.timestep)))

    @property
    def coupling_pole(self) -> float:
        """a = exp(-T / T_c) of the compliance damping's low-pass; 0 without damping."""
        if self.coupling_time_constant <= 0:
            return 0.0
        return math.exp(-self.timestep / self.coupling_time_constant)

    @property
    def settle_steps(self) -> int:
        """Control periods in a settle window."""
        return max(1, int(round(self.settle_window_s / self.timestep)))

    @property
    def movement(self) -> dmp.DMPConfig:
        """The DMP's constants the trial runs: `dmp`, its movement's duration T and cruise the
        skill's where the skill names them (`SkillConfig.movement_s`, `movement_cruise`)."""
        movement = self.dmp
        if self.search.movement_s > 0:
            movement = dataclasses.replace(movement, duration=self.search.movement_s)
        if self.search.movement_cruise > 0:
            movement = dataclasses.replace(movement, cruise=self.search.movement_cruise)
        return movement

    def replace(self, **changes) -> TrialConfig:
        return dataclasses.replace(self, **changes)


@dataclasses.dataclass(frozen=True)
class TrialResult:
    """Outcome of a batch of trials, in spec order (NumPy arrays, leading dim B)."""

    success: np.ndarray  # (B,) bool
    time_s: np.ndarray  # (B,) time to complete on success, else the time simulated
    final_tip_pos: np.ndarray  # (B, 3) true peg tip at the end, world frame
    peak_force: np.ndarray  # (B,) largest sensed force magnitude (N): what the controller saw
    reward: np.ndarray  # (B,) paper scale (38000 on success)
    unstable: np.ndarray  # (B,) bool: physics blew up or joints beyond max_joint_speed (failed)
    steps: np.ndarray  # (B,) physics steps simulated
    # (B,) bool: a failure ended early because it had settled (TrialConfig.end_settled)
    settled: np.ndarray
    # (B,) N: mean |F_k - F_(k-1)| of the true axial contact force (goal z, no sensor) over the
    # last TrialConfig.chatter_window_s of the trial (all of it if shorter). A force that
    # alternates by 100 N every step reads 100; a smooth press, a few tenths.
    chatter: np.ndarray
    protective_stop: np.ndarray  # (B,) bool: the sensed tool force passed max_tool_force (failed)

    def __len__(self) -> int:
        return int(self.success.shape[0])

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    @classmethod
    def from_arrays(cls, arrays) -> TrialResult:
        return cls(**{f.name: np.asarray(arrays[f.name]) for f in dataclasses.fields(cls)})

    @classmethod
    def concat(cls, results) -> TrialResult:
        return cls(
            **{
                f.name: np.concatenate([getattr(r, f.name) for r in results])
                for f in dataclasses.fields(cls)
            }
        )

    def summary(self) -> str:
        """One line: success rate, median time to complete, failures by cause."""
        n = len(self)
        ok = self.success
        median = float(np.median(self.time_s[ok])) if ok.any() else float("nan")
        return (
            f"{int(ok.sum())}/{n} succeeded ({100.0 * ok.mean():.1f} %), "
            f"median time {median:.2f} s, {int(self.unstable.sum())} unstable, "
            f"{int(self.protective_stop.sum())} protective stops, "
            f"{int(self.settled.sum())} settled, "
            f"mean reward {float(self.reward.mean()):.0f}; {self.contact_summary()}"
        )

    def contact_summary(self) -> str:
        """Peak sensed force (median, p99) and the chatter of the trials whose chatter counts
        (`chatter_counted`: median, share under CHATTER_LIMIT_N)."""
        peak = np.percentile(self.peak_force, [50, 99]) if len(self) else (np.nan, np.nan)
        long = self.chatter[chatter_counted(self.time_s)]
        median = float(np.median(long)) if long.size else float("nan")
        share = smooth_pct(long)
        return (
            f"peak sensed force median {peak[0]:.0f} N, p99 {peak[1]:.0f} N; chatter median "
            f"{median:.2f} N, {share:.1f} % under {CHATTER_LIMIT_N:g} N ({long.size} trials > "
            f"{CHATTER_MIN_TIME_S:g} s)"
        )


def control_config(config: TrialConfig, xp=np) -> ControlConfig:
    """The control step's constants for `config`, torque limits as an array of namespace `xp`."""
    return ControlConfig(
        tau=config.dmp.tau,
        alpha_s=config.dmp.alpha_s,
        k_ref=config.dmp.k_ref,
        pinv_damping=config.pinv_damping,
        torque_limits=xp.asarray(TORQUE_LIMITS),
        force_deadband=config.force_deadband,
        moment_deadband=config.moment_deadband,
        search=config.search,
        movement_s=config.movement.duration,
    )


@functools.lru_cache(maxsize=8)
def fitted_basis(config: dmp.DMPConfig) -> Basis:
    """The forcing term's basis and weights, fitted once per DMP config (NumPy, float64)."""
    centers, widths = dmp.basis_centers(config.n_basis, config.phase_span)
    weights = dmp.fit_forcing_weights(config)
    return Basis(np.asarray(weights), np.asarray(centers), np.asarray(widths))


def is_success(tip_pos, hole_origin, hole_axis, size, success_height: float):
    """(...,) bool: the tip passed the hole (inside its footprint) and is near the table.

    Measured in the hole's frame (`task.hole_frame`: origin (..., 3) on the axis at the board's
    bottom, unit axis (..., 3)): height along the axis < success_height, distance from it < size.
    """
    xp = tip_pos.__array_namespace__()
    offset = tip_pos - hole_origin
    height = xp.sum(offset * hole_axis, axis=-1)
    lateral = xp.linalg.vector_norm(offset - height[..., None] * hole_axis, axis=-1)
    return (height < success_height) & (lateral < size)


def trial_reward(success, tip_pos, hole_origin, start_distance, reward: RewardConfig):
    """(...,) paper-scale reward: `success` on success, else shaped by the tip's progress
    towards the hole's origin (on its axis at the board's bottom)."""
    xp = tip_pos.__array_namespace__()
    d_end = xp.linalg.vector_norm(tip_pos - hole_origin, axis=-1)
    progress = xp.clip(1.0 - d_end / xp.maximum(start_distance, 1e-6), 0.0, 1.0)
    return xp.where(success, reward.success, reward.shaped * progress)


def sensor_params(specs, config: TrialConfig) -> sensor.SensorParams:
    """The F/T pipeline's per-trial constants of `specs` (NumPy, leading dim B)."""
    return sensor.make_params(
        config.sensor,
        config.timestep,
        np.asarray(specs.sensor_seed, dtype=np.uint32),
        cutoff_scale=np.asarray(specs.sensor_cutoff_scale, dtype=np.float64),
        noise_scale=np.asarray(specs.sensor_noise_scale, dtype=np.float64),
        delay_offset=np.asarray(specs.sensor_delay_offset, dtype=np.int32),
    )


# How the chatter metric (TrialResult.chatter) is read, for every table of it: a trial's chatter
# counts only if the trial ran longer than CHATTER_MIN_TIME_S (one that ends sooner ends during
# the approach, and its window holds the movement and the first impact, not a press on contact),
# and a counted trial chatters if its chatter is CHATTER_LIMIT_N or more.
CHATTER_MIN_TIME_S = 1.2
CHATTER_LIMIT_N = 5.0


def chatter_counted(time_s) -> np.ndarray:
    """(...,) bool: the trials (their durations `time_s`, s) whose chatter counts."""
    return np.asarray(time_s, dtype=float) > CHATTER_MIN_TIME_S


def smooth_pct(counted) -> float:
    """% of `counted` chatter values (N; those `chatter_counted` keeps) under CHATTER_LIMIT_N;
    NaN where there are none."""
    counted = np.asarray(counted, dtype=float)
    return 100.0 * float((counted < CHATTER_LIMIT_N).mean()) if counted.size else math.nan


def chattering(chatter, time_s) -> np.ndarray:
    """(...,) bool: the trials whose chatter counts and is CHATTER_LIMIT_N or more."""
    return chatter_counted(time_s) & (np.asarray(chatter, dtype=float) >= CHATTER_LIMIT_N)


def chatter_of(ring, steps):
    """(...,) N: the chatter metric (TrialResult.chatter) from a ring (..., W) of |F_k - F_(k-1)|
    written at index k mod W, k >= 1, after `steps` (...,) control periods: the mean of the last
    min(steps - 1, W) entries."""
    xp = namespace_of(ring)
    count = xp.clip(xp.asarray(steps) - 1, 0, ring.shape[-1])
    return xp.where(count > 0, xp.sum(ring, axis=-1) / xp.maximum(count, 1), 0.0)


class SettleState(NamedTuple):
    """Per trial, the envelopes `settle_update` compares (a pytree under JAX)."""

    low: (
        object  # (..., 10) least [tcp position (3), wrench (6), fastest joint speed] in this window
    )
    high: object  # (..., 10) greatest
    last_low: object  # (..., 10) of the previous window
    last_high: object  # (..., 10)
    matched: object  # (...,) int: windows in a row whose envelope matched the previous one


def settle_start(batch_shape=(), xp=np) -> SettleState:
    """The state of trials at their start."""
    inf = xp.full((*batch_shape, 10), math.inf)
    return SettleState(inf, -inf, inf, -inf, xp.zeros(batch_shape, dtype=xp.int32))


def settle_observe(state: SettleState, qvel, tcp_pos, wrench) -> SettleState:
    """The state with this control period's joint speeds qvel (..., n), tcp position (..., 3)
    (what a robot measures; the peg is rigid on the flange) and sensed wrench (..., 6) in the
    current window's envelope."""
    xp = tcp_pos.__array_namespace__()
    speed = xp.max(xp.abs(qvel), axis=-1, keepdims=True)
    x = xp.concat([tcp_pos, wrench, speed], axis=-1)
    return state._replace(low=xp.minimum(state.low, x), high=xp.maximum(state.high, x))


def settle_close(state: SettleState, step, config: TrialConfig, period: int = 1) -> SettleState:
    """The state after control period `step` (physics steps since the trial's start) has been
    observed, the next one `period` steps later: when this one closes a window, the window's
    envelope is compared with the previous window's (if that one started at or after
    settle_after_s) and becomes the previous window."""
    xp = state.low.__array_namespace__()
    w = config.settle_steps
    tol = xp.asarray(
        [config.settle_tip_m] * 3 + [config.settle_force_n] * 3 + [config.settle_moment_nm] * 3
        + [config.settle_joint_speed], dtype=state.low.dtype,
    )  # fmt: skip
    same = xp.all(
        (xp.abs(state.low - state.last_low) <= tol) & (xp.abs(state.high - state.last_high) <= tol),
        axis=-1,
    )
    window = step // w
    first = (window - 1) * w  # the previous window's first step
    counted = (window >= 1) & (first * config.timestep >= config.settle_after_s - 1e-9)
    closes = (step + period) // w > window
    matched = xp.where(closes, xp.where(same & counted, state.matched + 1, 0), state.matched)
    c = closes[..., None]
    return SettleState(
        xp.where(c, math.inf, state.low),
        xp.where(c, -math.inf, state.high),
        xp.where(c, state.low, state.last_low),
        xp.where(c, state.high, state.last_high),
        matched,
    )


def settle_update(state: SettleState, step, qvel, tcp_pos, wrench, config, period: int = 1):
    """`settle_close` after `settle_observe`: one control period of the settle test (see
    TrialConfig.end_settled). Windows are steps [k W, (k + 1) W) of the trial,
    W = config.settle_steps. Written over the array-API namespace of its inputs, like the
    controller: the engines and the robot runtime share it; it acts on each trial alone.
    """
    return settle_close(settle_observe(state, qvel, tcp_pos, wrench), step, config, period)


def is_settled(state: SettleState, config: TrialConfig):
    """(...,) bool: the trial has settled and ends (if config.end_settled)."""
    return (state.matched >= config.settle_windows) & config.end_settled


def as_controller_params(params, batch: int) -> ControllerParams:
    """Validate and broadcast controller parameters to a batch of `batch` trials (NumPy).

    Accepts `ControllerParams` or physical vectors of shape (N,) or (batch, N), N = 38 (the
    controller) or 47 (and the contact search's learned constants, `params.SEARCH_RANGES`).
    """
    if not isinstance(params, ControllerParams):
        vec = np.asarray(params, dtype=np.float64)
        if (
            vec.ndim not in (1, 2)
            or vec.shape[-1] not in (N_PARAMS, N_LEARNED)
            or (vec.ndim == 2 and vec.shape[0] != batch)
        ):
            raise UsageError(
                f"controller parameters must have shape (N,) or ({batch}, N), N = {N_PARAMS} or "
                f"{N_LEARNED}, got {vec.shape}"
            )
        params = controller_from_vector(vec)
    k_t = np.broadcast_to(np.asarray(params.k_t, dtype=np.float64), (batch,))
    k_theta = np.broadcast_to(np.asarray(params.k_theta, dtype=np.float64), (batch,))
    compliance = np.broadcast_to(np.asarray(params.compliance, dtype=np.float64), (batch, 6, 6))
    for name, value in (("k_t", k_t), ("k_theta", k_theta), ("compliance", compliance)):
        if not np.all(np.isfinite(value)):
            raise UsageError(f"controller parameter {name} has NaN or infinite values")
    if np.any(k_t <= 0) or np.any(k_theta <= 0):
        raise UsageError("controller stiffnesses k_t and k_theta must be positive")
    search = None
    if params.search is not None:
        values = {}
        for name, value in params.search._asdict().items():
            if value is None:  # a field the engine fills per trial (`search.for_part`)
                continue
            value = np.broadcast_to(np.asarray(value, dtype=np.float64), (batch,)).copy()
            low, high, _ = SEARCH_RANGES[name]
            if not np.all((value >= low) & (value <= high)):
                raise UsageError(f"the search's {name} must lie in [{low}, {high}]")
            values[name] = value
        search = type(params.search)(**values)
    return ControllerParams(k_t.copy(), k_theta.copy(), compliance.copy(), search)
