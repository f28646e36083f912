"""robot/sim_arm.py: the simulated arm reads MuJoCo's quantities at the set-up, holds a command
over its period, lags it like a drive, and refuses bad arguments."""

from __future__ import annotations

import numpy as np
import pytest

from mjx_peg.engines.trial import TrialConfig
from mjx_peg.robot.runtime import HoleEstimate, SkillRuntime, run_skill
from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world import constants
from mjx_peg.world.kinematics import fk_tcp, jacobian_tcp
from mjx_peg.world.task import TaskConfig, sample_trials

SHORT = TrialConfig(time_limit_s=3.0)
TASK = TaskConfig(shapes=("circle", "square"), linear_error=0.002, angular_error=np.deg2rad(2.0))
SPECS = sample_trials(TASK, 3, 1)


def test_the_first_reading_is_the_set_up_and_the_hold_torque_keeps_it():
    """At the set-up the arm rests at the trial's q0: t = 0, qd = 0, the tcp and its Jacobian
    those of the DH model (the MJCF's tcp site is DH tool0 + PEG_LENGTH) within 1e-9, H
    symmetric positive definite; sending the holding torque keeps q within 1e-6 rad."""
    arm = SimArm(SPECS, 0)
    state = arm.read()
    assert state.t == 0.0 and arm.period == pytest.approx(0.002)
    np.testing.assert_array_equal(state.q, SPECS.q0[0])
    np.testing.assert_array_equal(state.qd, np.zeros(6))
    pos, rot = fk_tcp(state.q, constants.PEG_LENGTH)
    np.testing.assert_allclose(state.tcp_pos, pos, atol=1e-9, rtol=0)
    np.testing.assert_allclose(state.tcp_rot, rot, atol=1e-9, rtol=0)
    np.testing.assert_allclose(state.jac, jacobian_tcp(state.q, constants.PEG_LENGTH), atol=1e-9)
    np.testing.assert_array_equal(state.jac_dot, np.zeros((6, 6)))  # at rest
    np.testing.assert_allclose(state.mass, state.mass.T, atol=1e-12)
    assert np.linalg.eigvalsh(state.mass).min() > 0
    np.testing.assert_allclose(state.bias, arm.hold_torque, atol=1e-12)  # h at rest = ctrl
    for _ in range(50):
        arm.send(arm.hold_torque)
        state = arm.read()
    assert state.t == pytest.approx(0.1) and np.abs(state.q - SPECS.q0[0]).max() < 1e-6
    assert not arm.inserted()


def test_actuator_lag_is_a_first_order_response_to_the_command():
    """With a 5 ms lag, the joints get the set-up's holding torque plus 1 - exp(-t / 5 ms) of a
    step in the command, at every physics step (2 ms); 63 % of it after 5 ms (2.5 steps)."""
    specs = SPECS
    lagged, direct = SimArm(specs, 0, actuator_lag_s=0.005), SimArm(specs, 0)
    hold = lagged.hold_torque.copy()
    step = np.array([2.0, -3.0, 1.0, 0.5, -0.5, 0.2])
    applied = []
    for arm in (lagged, direct):
        arm.read()
        arm.send(hold + step)
    applied.append(lagged.data.ctrl[lagged.ids.actuator_ids] - hold)
    for _ in range(4):
        lagged.read()
        lagged.send(hold + step)
        applied.append(lagged.data.ctrl[lagged.ids.actuator_ids] - hold)
    k = np.arange(1, 6)[:, None]
    np.testing.assert_allclose(applied, (1 - np.exp(-k * 0.002 / 0.005)) * step, rtol=1e-12)
    np.testing.assert_allclose(direct.data.ctrl[direct.ids.actuator_ids], hold + step)
    four = SimArm(specs, 0, command_steps=4, actuator_lag_s=0.005)  # one command, four steps
    four.read()
    four.send(four.hold_torque + step)
    np.testing.assert_allclose(four.data.ctrl[four.ids.actuator_ids] - four.hold_torque,
                               (1 - np.exp(-4 * 0.002 / 0.005)) * step, rtol=1e-12)  # fmt: skip


def test_command_rate_holds_the_torque_between_commands():
    specs, vec = SPECS, baseline_params()
    arm = SimArm(specs, 0, command_steps=4)
    sent = []
    send = arm.send

    def spy(torque):
        before = arm.steps
        send(torque)
        sent.append((before, arm.steps, arm.data.ctrl.copy(), torque.copy()))

    arm.send = spy
    runtime = SkillRuntime(vec, HoleEstimate.of_trial(specs, 0), SHORT)
    run = run_skill(arm, runtime, 0.5, done=lambda s: False)
    assert arm.period == pytest.approx(0.008)
    assert run.commands == 63 and len(sent) == 63  # ceil(0.5 s / 8 ms)
    np.testing.assert_allclose(np.diff(run.log["t"]), 0.008, atol=1e-12)
    for before, after, ctrl, torque in sent:
        assert after - before == 4
        np.testing.assert_array_equal(ctrl, torque)  # held through the whole period
    assert run.time_s == pytest.approx(0.504)


def test_sim_arm_rejects_bad_arguments():
    specs = SPECS
    with pytest.raises(ValueError, match="command_steps must be a positive integer"):
        SimArm(specs, 0, command_steps=0)
    with pytest.raises(ValueError, match="trial index 1 is outside the 1 trials"):
        SimArm(specs, 1)
    with pytest.raises(ValueError, match="actuator_lag_s must be a number >= 0"):
        SimArm(specs, 0, actuator_lag_s=-0.005)
    assert constants.SHAPES[int(specs.shape_id[0])] in ("circle", "square")
