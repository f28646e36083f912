"""robot/arm_model.py: the training scene's H, h and g against MuJoCo's own quantities and the
simulated arm's readings; the controller's model decoded column by column and refused when no
UR5e could have it."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjx_peg.robot.arm_model import ControllerArmModel, ModelError, MujocoArmModel, check_inertia
from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.world import scene
from mjx_peg.world.task import TaskConfig, sample_trials

Q = np.array([0.3, -1.4, 1.9, -2.2, -1.3, 0.4])
QD = np.array([0.2, -0.3, 0.4, 0.1, -0.2, 0.5])


def test_mujoco_model_is_mujocos_inertia_bias_and_gravity():
    """H = mj_fullM, h = qfrc_bias - qfrc_passive (joint damping) at (q, qd), g = qfrc_bias at
    rest, all of the training scene (peg at its nominal grasp), to 1e-12."""
    model = MujocoArmModel("square", 0.05)
    reference = scene.load_model("square", 0.05)
    data = mujoco.MjData(reference)
    ids = scene.scene_ids(reference)
    data.qpos[ids.qpos_adr], data.qvel[ids.dof_adr] = Q, QD
    mujoco.mj_forward(reference, data)
    full = np.zeros((reference.nv, reference.nv))
    mujoco.mj_fullM(reference, data, full)
    dof = ids.dof_adr
    mass, bias = model.dynamics(Q, QD)
    np.testing.assert_allclose(mass, full[np.ix_(dof, dof)], rtol=0, atol=1e-12)
    np.testing.assert_allclose(bias, data.qfrc_bias[dof] - data.qfrc_passive[dof], atol=1e-12)
    assert np.abs(data.qfrc_passive[dof]).max() > 1e-3  # the damping is there to be removed
    data.qvel[:] = 0.0
    mujoco.mj_forward(reference, data)
    np.testing.assert_allclose(model.gravity(Q), data.qfrc_bias[dof], rtol=0, atol=1e-12)
    np.testing.assert_allclose(model.dynamics(Q, np.zeros(6))[1], model.gravity(Q), atol=1e-12)


def test_mujoco_model_gives_what_the_simulated_arm_reads():
    """On a trial at its nominal grasp, the model's H and h at the arm's reading are the
    reading's, to 1e-12, after the arm has moved."""
    task = TaskConfig(shapes=("circle",), linear_error=0.002, angular_error=0.0,
                      grasp_model="flange")  # fmt: skip
    specs = sample_trials(task, 0, 1)
    specs.grasp_error[:] = 0.0
    arm = SimArm(specs, 0)
    for torque in (arm.hold_torque + 2.0, arm.hold_torque - 1.0, arm.hold_torque):
        state = arm.read()
        arm.send(torque)
    state = arm.read()
    assert np.abs(state.qd).max() > 1e-3
    mass, bias = MujocoArmModel("circle", float(specs.size[0])).dynamics(state.q, state.qd)
    np.testing.assert_allclose(mass, state.mass, rtol=0, atol=1e-12)
    np.testing.assert_allclose(bias, state.bias, rtol=0, atol=1e-12)


class _Control:
    """An RTDEControlInterface's model calls, answering fixed numbers."""

    def __init__(self, mass, bias):
        self.mass, self.bias = list(mass), list(bias)

    def getMassMatrix(self, q, include_rotors_inertia):  # noqa: N802 (ur_rtde's name)
        return self.mass

    def getCoriolisAndCentrifugalTorques(self, q, qd):  # noqa: N802
        return self.bias


H = np.diag([3.0, 2.5, 1.0, 0.2, 0.1, 0.05]) + 0.01 * (np.ones((6, 6)) - np.eye(6))


def test_controller_model_reads_ur_rtdes_column_order_and_adds_no_gravity():
    skew = H.copy()
    skew[0, 1] += 0.5  # told apart by the order
    skew[1, 0] += 0.5
    skew[0, 2] -= 0.004
    skew[2, 0] -= 0.004
    column_major = skew.ravel(order="F")
    mass, bias = ControllerArmModel(_Control(column_major, np.arange(6.0))).dynamics(Q, QD)
    np.testing.assert_array_equal(mass, skew)
    np.testing.assert_array_equal(bias, np.arange(6.0))
    np.testing.assert_array_equal(ControllerArmModel(None).gravity(Q), np.zeros(6))


@pytest.mark.parametrize(
    "mass, bias, message",
    [
        (np.zeros(36), np.zeros(6), "diagonal"),
        (H.ravel(), np.zeros(5), "returned 36 inertia and 5 bias numbers"),
        (np.where(np.eye(6) > 0, H, np.nan).ravel(), np.zeros(6), "NaN or infinite"),
        ((H + np.triu(np.full((6, 6), 0.1), 1)).ravel(), np.zeros(6), "not symmetric"),
        ((H + 2.9 * (np.ones((6, 6)) - np.eye(6))).ravel(), np.zeros(6), "positive definite"),
        (H.ravel(), np.full(6, 150.0), "Coriolis torques are not sane"),
    ],
)
def test_controller_model_refuses_what_no_ur5e_has(mass, bias, message):
    with pytest.raises(ModelError, match=message):
        ControllerArmModel(_Control(mass, bias)).dynamics(Q, QD)


def test_check_inertia_takes_the_training_scenes_inertia():
    check_inertia(MujocoArmModel("circle", 0.05).dynamics(Q, QD)[0])
