"""The F/T sensor in the loop: the wrench the controller sees, defined once for every arm.

The contact wrench reaches the controller the way a real wrist F/T sensor reports it, through one
pipeline shared by both engines, the simulated arm and the robot runtime (six axes, the sensor's
own frame, tared: the external wrench on the peg, CONVENTIONS.md):

    true      w_k         external wrench of control period k (the physics' last step)
    sample    s_k = w_j + b + e_j,  j = k - (k mod n)    every n-th period, held in between;
                          e_j ~ N(0, sigma^2) per axis, b ~ U(-beta, beta) per axis and trial;
                          the tare (k = 0) is exact: b and e start at k = 1
    delay     r_k = s_(k-d)                            d control periods of latency
    filter    m_k = a m_(k-1) + (1 - a) r_k,  a = exp(-2 pi f_c T)   first-order low-pass (EMA)

(`hardware_step` is the sensor itself: sampling, noise, bias and delay; `filter_step` is the
software filter every deployment runs on the reading.) The engines run both stages; the simulated
arm (`robot/sim_arm.py`) runs the hardware stage on MuJoCo's reading, as a real arm's own sensor
path does, and the robot runtime runs the pipeline with `filter_params`: a sensor of no noise,
bias, delay or hold, whose filter is the software one, so a run on the simulated arm sees the
engine's readings.

UR5e built-in F/T sensor (the defaults of `SensorConfig`):
- Datasheet (Universal Robots, UR5e technical specifications, "Force/torque sensor, tool
  flange", as reproduced in Li et al., "Trajectory-aware feedforward admittance control ... in a
  teleoperated robotic ultrasound system", Control Engineering Practice 2025,
  doi:10.1016/j.conengprac.2025.106674, Table 2, measured on a UR5e through ur_rtde):
  force x-y-z range +-50 N, precision +-3.5 N, accuracy +-4.0 N; torque x-y-z range +-10 N m,
  precision +-0.2 N m, accuracy +-0.3 N m; read at 500 Hz over RTDE. The same paper low-pass
  filters the readings at 50 Hz before using them.
- Users: the built-in sensors are noisy and drift (a CB-series UR5's internal force estimate had
  a 3.6 N standard deviation against 0.6 N for an external Robotiq FT 300, UR forum "Internal
  Force Sensor properties"; a UR e-Series wrench did not return to zero after an 80 N load,
  github.com/UniversalRobots/Universal_Robots_ROS_Driver/issues/670), and integrated sensors
  need filtering that adds latency (Bota Systems, "Choosing the right force torque sensor").
- Deployments filter: FORGE (Noseworthy et al. 2024, Isaac Lab's `forge_env_cfg.py`) smooths the
  force with an EMA of factor 0.25 per step and trains with 1 N of force noise.

Hence: 500 Hz sampling; noise sigma = 1.2 N and 0.07 N m (the datasheet precision read as a
3-sigma band; FORGE's 1 N is the same size); a residual bias within +-1 N and +-0.1 N m (the
accuracy beyond the precision, 0.5 N and 0.1 N m, rounded up for drift over a trial); one control
period of latency beyond the physics' own step (the sensor's internal processing); a 50 Hz
first-order filter (Li et al.'s; an EMA factor of 0.47 at 500 Hz, between no filter and FORGE's).
The datasheet's +-50 N is the calibrated range, not a clip: the arm keeps reporting beyond it
(its tool-force protective stop sits at 150 N), so the pipeline does not saturate.

Noise that every engine reproduces: each random number is a counter-based hash of the trial's
`sensor_seed` (drawn with the spec) and the period index, in uint32 arithmetic that NumPy and JAX
evaluate identically, so a trial's readings do not depend on its engine, batch, row or process.

Written over the array-API namespace of the inputs (batched over `...`); this module imports
neither numpy nor jax. Carried state is the NamedTuple `SensorState`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

from mjx_peg.array_api import namespace_of
from mjx_peg.errors import UsageError

# Counter streams of the hash: noise of sample j, axis i uses counters 2 (6 j + i) and +1.
_BIAS_STREAM = 0x68E31DA4  # xor-ed into the seed for the per-trial bias
_UINT32 = 0xFFFFFFFF


@dataclasses.dataclass(frozen=True)
class SensorConfig:
    """The F/T pipeline's nominal settings: the UR5e's built-in sensor (module docstring)."""

    rate_hz: float = 500.0  # samples per second (UR RTDE); held between samples
    cutoff_hz: float = 50.0  # first-order low-pass; math.inf: no filter
    delay_steps: int = 1  # control periods of latency beyond the physics' own step
    force_noise: float = 1.2  # N, per-axis standard deviation (datasheet precision +-3.5 N)
    torque_noise: float = 0.07  # N m (datasheet precision +-0.2 N m)
    force_bias: float = 1.0  # N, residual bias after taring: uniform within +-
    torque_bias: float = 0.1  # N m
    max_delay_steps: int = 8  # length of the delay line (bounds randomized delays)

    def __post_init__(self):
        for name in ("rate_hz", "cutoff_hz"):
            value = getattr(self, name)
            if not (value > 0 and not math.isnan(value)):
                raise UsageError(f"SensorConfig.{name} must be positive, got {value!r}")
        if not math.isfinite(self.rate_hz):
            raise UsageError(f"SensorConfig.rate_hz must be finite, got {self.rate_hz!r}")
        for name in ("force_noise", "torque_noise", "force_bias", "torque_bias"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise UsageError(f"SensorConfig.{name} must be a number >= 0, got {value!r}")
        for name in ("delay_steps", "max_delay_steps"):
            value = getattr(self, name)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= 0):
                raise UsageError(f"SensorConfig.{name} must be an integer >= 0, got {value!r}")
        if self.delay_steps > self.max_delay_steps:
            raise UsageError(
                f"SensorConfig.delay_steps ({self.delay_steps}) exceeds max_delay_steps "
                f"({self.max_delay_steps})"
            )

    def hold_steps(self, timestep: float) -> int:
        """Control periods between two samples (at least 1)."""
        return max(1, int(round(1.0 / (self.rate_hz * timestep))))

    def replace(self, **changes) -> SensorConfig:
        return dataclasses.replace(self, **changes)


class SensorParams(NamedTuple):
    """Per-trial constants of the pipeline (arrays, leading dims `...`)."""

    seed: object  # (...,) uint32: the trial's key for every random draw
    hold: object  # (...,) integer: control periods between samples
    delay: object  # (...,) integer: latency in control periods, 0 <= delay < history length
    alpha: object  # (...,) float: filter pole a = exp(-2 pi f_c T), 0 without filter
    noise: object  # (..., 6) float: per-axis standard deviation (N, N m)
    bias: object  # (..., 6) float: residual bias (N, N m)


class SensorState(NamedTuple):
    """What the pipeline carries from one control period to the next."""

    history: object  # (..., H, 6) the last H samples, newest first (H = max delay + 1)
    filtered: object  # (..., 6) the filter's output


# -- counter-based random numbers ------------------------------------------------------------------


def _u32(value, xp):
    return xp.asarray(value, dtype=xp.uint32)


def mix32(x):
    """uint32 avalanche hash (Wellons' lowbias32): every input bit flips each output bit with
    probability ~1/2. Wrapping uint32 arithmetic, the same in NumPy and JAX."""
    xp = namespace_of(x)
    x = x ^ (x >> _u32(16, xp))
    x = x * _u32(0x21F0AAAD, xp)
    x = x ^ (x >> _u32(15, xp))
    x = x * _u32(0x735A2D97, xp)
    return x ^ (x >> _u32(15, xp))


def counter_uniform(seed, counter, dtype):
    """(...) uniform numbers in (0, 1) of `dtype` from uint32 `seed` and `counter` (broadcast)."""
    xp = namespace_of(seed, counter)
    h = mix32(mix32(counter) ^ seed)
    top = xp.astype(h >> _u32(8, xp), dtype)  # 24 bits: exact in float32 and float64
    return (top + 0.5) * (2.0**-24)


def counter_normal(seed, counter, dtype):
    """(...) standard normal numbers (Box-Muller on counters 2c and 2c + 1)."""
    xp = namespace_of(seed, counter)
    two = _u32(2, xp)
    u1 = counter_uniform(seed, counter * two, dtype)
    u2 = counter_uniform(seed, counter * two + _u32(1, xp), dtype)
    return xp.sqrt(-2.0 * xp.log(u1)) * xp.cos((2.0 * math.pi) * u2)


def _axis_counters(step, xp):
    """(..., 6) uint32 counters 6 step + i of the six axes."""
    k = xp.astype(xp.asarray(step), xp.uint32)
    return k[..., None] * _u32(6, xp) + xp.arange(6, dtype=xp.uint32)


# -- the pipeline ----------------------------------------------------------------------------------


def make_params(
    config: SensorConfig,
    timestep: float,
    seed,
    cutoff_scale=1.0,
    noise_scale=1.0,
    delay_offset=0,
    dtype=None,
) -> SensorParams:
    """SensorParams of trials with uint32 `seed` (...,) and the spec's randomization factors.

    cutoff = config.cutoff_hz * cutoff_scale; noise = config noise * noise_scale;
    delay = clip(config.delay_steps + delay_offset, 0, config.max_delay_steps). The bias is drawn
    from the seed: uniform within +-(force_bias, torque_bias) per axis.
    """
    xp = namespace_of(seed)
    seed = xp.asarray(seed, dtype=xp.uint32)
    dtype = dtype or xp.float64
    shape = tuple(seed.shape)
    scale = xp.asarray([config.force_noise] * 3 + [config.torque_noise] * 3, dtype=dtype)
    noise = scale * xp.asarray(noise_scale, dtype=dtype)[..., None]
    noise = xp.broadcast_to(noise, shape + (6,))
    bias_range = xp.asarray([config.force_bias] * 3 + [config.torque_bias] * 3, dtype=dtype)
    u = counter_uniform(seed[..., None] ^ _u32(_BIAS_STREAM, xp), xp.arange(6, dtype=xp.uint32),
                        dtype)  # fmt: skip
    bias = (2.0 * u - 1.0) * bias_range
    cutoff = config.cutoff_hz * xp.asarray(cutoff_scale, dtype=dtype)
    alpha = xp.broadcast_to(xp.exp(-2.0 * math.pi * timestep * cutoff), shape)
    delay = config.delay_steps + xp.asarray(delay_offset, dtype=xp.int32)
    delay = xp.broadcast_to(xp.clip(delay, 0, config.max_delay_steps), shape)
    hold = xp.broadcast_to(xp.asarray(config.hold_steps(timestep), dtype=xp.int32), shape)
    return SensorParams(seed, hold, delay, alpha, noise, bias)


def filter_params(config: SensorConfig, timestep: float, seed, period_steps: int = 1,
                  dtype=None) -> SensorParams:  # fmt: skip
    """SensorParams of a reading that arrives as an arm's own sensor path delivers it (sampled,
    tared, with whatever noise, bias and latency it has): no noise, bias or delay, a sample every
    period; only the software filter at `config.cutoff_hz`, its pole for a control period of
    `period_steps` physics steps of `timestep`, a^n (the reading held over n steps). seed:
    (...,) uint32, the trials' shape and array namespace (nothing is drawn)."""
    quiet = config.replace(force_noise=0.0, torque_noise=0.0, force_bias=0.0, torque_bias=0.0,
                           delay_steps=0)  # fmt: skip
    params = make_params(quiet, timestep, seed, dtype=dtype)
    xp = namespace_of(params.alpha)
    return params._replace(hold=xp.ones_like(params.hold), alpha=params.alpha**period_steps)


def initial_state(params: SensorParams, history_length: int, dtype=None) -> SensorState:
    """The state at the tare: every past sample and the filter read zero."""
    xp = namespace_of(params.noise)
    dtype = dtype or params.noise.dtype
    shape = tuple(params.noise.shape[:-1])
    return SensorState(
        xp.zeros(shape + (history_length, 6), dtype=dtype), xp.zeros(shape + (6,), dtype=dtype)
    )


def hardware_step(params: SensorParams, history, wrench, step):
    """(reading (..., 6), history): the sensor's sampling, noise, bias and delay at period `step`.

    wrench: (..., 6) true external wrench in the sensor frame (tared); step (...,) integer period
    index since the tare (the tare is period 0: no noise, no bias). history: (..., H, 6).
    """
    xp = namespace_of(wrench, history)
    step = xp.asarray(step)
    fresh = wrench + params.noise * counter_normal(
        params.seed[..., None], _axis_counters(step, xp), wrench.dtype
    )
    fresh = xp.where((step > 0)[..., None], fresh + params.bias, wrench)
    sampled = (step % xp.asarray(params.hold, dtype=step.dtype)) == 0
    sample = xp.where(sampled[..., None], fresh, history[..., 0, :])
    history = xp.concat([sample[..., None, :], history[..., :-1, :]], axis=-2)
    length = history.shape[-2]
    pick = xp.arange(length, dtype=xp.int32) == xp.asarray(params.delay, dtype=xp.int32)[..., None]
    reading = xp.sum(xp.where(pick[..., None], history, 0.0), axis=-2)
    return reading, history


def filter_step(filtered, reading, alpha):
    """(..., 6) first-order low-pass: a m_(k-1) + (1 - a) r_k; alpha (...,)."""
    a = alpha[..., None]
    return a * filtered + (1.0 - a) * reading


def step(params: SensorParams, state: SensorState, wrench, step_index):
    """(sensed (..., 6), state): the whole pipeline for one control period (engines)."""
    reading, history = hardware_step(params, state.history, wrench, step_index)
    filtered = filter_step(state.filtered, reading, params.alpha)
    return filtered, SensorState(history, filtered)


__all__ = [
    "SensorConfig",
    "SensorParams",
    "SensorState",
    "counter_normal",
    "counter_uniform",
    "filter_params",
    "filter_step",
    "hardware_step",
    "initial_state",
    "make_params",
    "mix32",
    "step",
]
