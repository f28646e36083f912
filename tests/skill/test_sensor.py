"""The F/T pipeline (`mjx_peg.skill.sensor`): step response and delay against their closed form,
sampling, noise and bias statistics, the exact tare, and the same readings in NumPy and JAX."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjx_peg.skill import sensor

T = 0.002
QUIET = sensor.SensorConfig(force_noise=0.0, torque_noise=0.0, force_bias=0.0, torque_bias=0.0)


def _params(config, n=1, seed=7, **kw):
    return sensor.make_params(config, T, np.arange(n, dtype=np.uint32) * 7919 + seed, **kw)


def _run(config, wrenches, seed=7, stage="all", **kw):
    """(steps, batch, 6) outputs of the pipeline for inputs (steps, batch, 6)."""
    steps, batch = wrenches.shape[:2]
    params = _params(config, batch, seed, **kw)
    state = sensor.initial_state(params, config.max_delay_steps + 1)
    out = []
    for k in range(steps):
        index = np.full(batch, k)
        if stage == "hardware":
            reading, history = sensor.hardware_step(params, state.history, wrenches[k], index)
            state = state._replace(history=history)
            out.append(reading)
        else:
            sensed, state = sensor.step(params, state, wrenches[k], index)
            out.append(sensed)
    return np.array(out)


@pytest.mark.parametrize("delay", [0, 1, 3])
@pytest.mark.parametrize("cutoff", [25.0, 50.0, math.inf])
def test_step_response_and_delay_are_the_closed_form(delay, cutoff):
    """A step of w from period 1: m_k = w (1 - a^(k - d)) for k > d, else 0; a = e^(-2 pi f T)."""
    config = QUIET.replace(delay_steps=delay, cutoff_hz=cutoff)
    w = np.array([10.0, -4.0, 30.0, 0.5, -0.2, 0.1])
    steps = 80
    inputs = np.zeros((steps, 1, 6))
    inputs[1:] = w
    out = _run(config, inputs)[:, 0]
    a = math.exp(-2.0 * math.pi * cutoff * T)
    k = np.arange(steps)
    expected = np.where(k > delay, 1.0 - a ** np.maximum(k - delay, 0), 0.0)[:, None] * w
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-12)
    if math.isfinite(cutoff):  # the 63 % point comes one time constant after the delay
        tc = 1.0 / (2.0 * math.pi * cutoff)
        first = int(np.argmax(out[:, 2] >= (1.0 - math.exp(-1.0)) * w[2]))
        assert abs(first - delay - tc / T) <= 1.0


@pytest.mark.parametrize("delay", [0, 2, 5])
def test_an_impulse_arrives_exactly_delay_periods_later(delay):
    inputs = np.zeros((20, 1, 6))
    inputs[5, 0, 1] = 3.0
    out = _run(QUIET.replace(delay_steps=delay), inputs, stage="hardware")[:, 0, 1]
    assert np.flatnonzero(out).tolist() == [5 + delay]
    assert out[5 + delay] == 3.0


def test_sampling_holds_the_reading_between_samples():
    config = QUIET.replace(rate_hz=125.0, delay_steps=0)  # a sample every 4 periods at 500 Hz
    assert config.hold_steps(T) == 4
    inputs = np.arange(1, 21, dtype=float)[:, None, None] * np.ones((20, 1, 6))
    out = _run(config, inputs, stage="hardware")[:, 0, 0]
    assert out.tolist() == [1, 1, 1, 1, 5, 5, 5, 5, 9, 9, 9, 9, 13, 13, 13, 13, 17, 17, 17, 17]


@pytest.mark.parametrize("period_steps", [1, 4])
def test_an_arms_own_sensor_path_gets_the_software_filter_alone(period_steps):
    """`filter_params`: whatever the nominal sensor's noise, bias, latency and sampling, the
    pipeline passes an arm's reading through the software filter alone, bit for bit, its pole
    a^n for a command every n physics steps."""
    config = sensor.SensorConfig(rate_hz=125.0, delay_steps=3)  # none of these may act
    params = sensor.filter_params(config, T, np.zeros(2, np.uint32), period_steps)
    a = math.exp(-2.0 * math.pi * config.cutoff_hz * T) ** period_steps
    np.testing.assert_allclose(params.alpha, a, rtol=1e-15)
    state = sensor.initial_state(params, config.max_delay_steps + 1)
    filtered = np.zeros((2, 6))
    readings = np.random.default_rng(0).normal(0.0, 20.0, (30, 2, 6))
    for k, reading in enumerate(readings):
        sensed, state = sensor.step(params, state, reading, np.full(2, k))
        filtered = sensor.filter_step(filtered, reading, params.alpha)
        np.testing.assert_array_equal(sensed, filtered)


def test_noise_and_bias_have_their_statistics_and_the_tare_is_exact():
    config = sensor.SensorConfig(delay_steps=0, cutoff_hz=math.inf)
    steps, batch = 4000, 4
    out = _run(config, np.zeros((steps, batch, 6)), stage="hardware")
    assert np.all(out[0] == 0.0)  # the tare: no noise, no bias
    params = _params(config, batch)
    bias = params.bias
    limit = np.array([config.force_bias] * 3 + [config.torque_bias] * 3)
    assert np.all(np.abs(bias) <= limit) and np.all(bias != 0.0)
    sigma = np.array([config.force_noise] * 3 + [config.torque_noise] * 3)
    mean = out[1:].mean(axis=0)
    std = out[1:].std(axis=0)
    np.testing.assert_allclose(mean, bias, atol=float(4 * sigma.max() / math.sqrt(steps)))
    np.testing.assert_allclose(std, np.broadcast_to(sigma, std.shape), rtol=0.05)
    # Independent axes, trials and periods.
    noise = (out[1:] - bias).reshape(-1, 6)
    corr = np.corrcoef(noise.T)
    assert np.abs(corr - np.eye(6)).max() < 0.05
    lag = np.corrcoef(out[1:-1, 0, 0], out[2:, 0, 0])[0, 1]
    assert abs(lag) < 0.05


def test_the_trial_seed_decides_every_draw():
    config = sensor.SensorConfig()
    inputs = np.random.default_rng(0).normal(size=(50, 3, 6))
    a = _run(config, inputs, seed=11)
    b = _run(config, inputs, seed=11)
    c = _run(config, inputs, seed=12)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0.1
    # A trial's readings do not depend on the rows next to it (batch layout).
    params = _params(config, 3, seed=11)
    alone = sensor.make_params(config, T, params.seed[1:2])
    np.testing.assert_array_equal(alone.bias[0], params.bias[1])


def test_randomization_factors_scale_the_pipeline():
    config = sensor.SensorConfig()
    p = _params(config, 2, cutoff_scale=np.array([0.5, 2.0]), noise_scale=np.array([2.0, 0.5]),
                delay_offset=np.array([-1, 9]))  # fmt: skip
    np.testing.assert_allclose(p.alpha, np.exp(-2 * math.pi * T * np.array([25.0, 100.0])))
    np.testing.assert_allclose(p.noise[:, 0], [2.4, 0.6])
    assert p.delay.tolist() == [0, config.max_delay_steps]  # clipped to the delay line


def test_hash_is_fixed():
    """The counter-based hash is the contract between engines: pin a few values."""
    x = np.array([0, 1, 2, 0xDEADBEEF, 0xFFFFFFFF], dtype=np.uint32)
    assert sensor.mix32(x).tolist() == [0, 2261973619, 229111015, 707447538, 2578835075]
    u = sensor.counter_uniform(np.uint32(5), np.arange(3, dtype=np.uint32), np.float64)
    assert np.all((u > 0) & (u < 1))


def test_numpy_and_jax_give_the_same_readings(x64):
    import jax
    import jax.numpy as jnp

    config = sensor.SensorConfig(rate_hz=250.0)
    seeds = np.array([3, 99, 2**31 + 5], dtype=np.uint32)
    inputs = np.random.default_rng(1).normal(size=(30, 3, 6)) * 20
    ref = []
    params = sensor.make_params(config, T, seeds, delay_offset=np.array([0, 1, 2]))
    state = sensor.initial_state(params, config.max_delay_steps + 1)
    pj = sensor.make_params(config, T, jnp.asarray(seeds), delay_offset=jnp.asarray([0, 1, 2]))
    sj = sensor.initial_state(pj, config.max_delay_steps + 1)
    step = jax.jit(sensor.step)
    for k in range(30):
        out, state = sensor.step(params, state, inputs[k], np.full(3, k))
        outj, sj = step(pj, sj, jnp.asarray(inputs[k]), jnp.full(3, k))
        ref.append(out)
        np.testing.assert_allclose(np.asarray(outj), out, rtol=0, atol=1e-9)
    # float32 (the MJX engine's default): the same draws to float32 precision
    pf = sensor.make_params(config, T, jnp.asarray(seeds), dtype=jnp.float32)
    np.testing.assert_allclose(np.asarray(pf.bias), params.bias, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize(
    "changes",
    [
        {"rate_hz": 0.0},
        {"cutoff_hz": -1.0},
        {"force_noise": -1.0},
        {"delay_steps": 9},
        {"max_delay_steps": -1},
        {"delay_steps": 1.5},
    ],  # fmt: skip
)
def test_bad_configs_raise(changes):
    with pytest.raises(ValueError, match="SensorConfig"):
        sensor.SensorConfig(**changes)
