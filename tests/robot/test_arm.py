"""robot/arm.py: what an arm gives the skill each period. Both arms the runtime drives (the
simulated arm, and the UR5e adapter over the simulated UR5e) read ArmStates of the shapes, frames
and units arm.py states, and read the same set-up alike."""

from __future__ import annotations

import numpy as np
import pytest

from mjx_peg.robot.arm import ArmState
from mjx_peg.robot.arm_model import MujocoArmModel
from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.robot.sim_ur5e import SimulatedUR5e
from mjx_peg.robot.ur5e import UR5eArm
from mjx_peg.world import constants
from mjx_peg.world.task import TaskConfig, sample_trials

TASK = TaskConfig(shapes=("square",), linear_error=0.002, angular_error=0.0, grasp_model="flange")
SPECS = sample_trials(TASK, 5, 1)
SPECS.grasp_error[:] = 0.0  # the adapter's model of the arm holds the peg at its nominal grasp
SHAPES = {"t": (), "q": (6,), "qd": (6,), "tcp_pos": (3,), "tcp_rot": (3, 3), "jac": (6, 6),
          "jac_dot": (6, 6), "mass": (6, 6), "bias": (6,), "force": (3,), "torque": (3,),
          "ft_pos": (3,), "ft_rot": (3, 3)}  # fmt: skip


def _arms():
    """The simulated arm and the UR5e adapter over a simulated UR5e, at the same set-up."""
    robot = SimulatedUR5e(SimArm(SPECS, 0))
    model = MujocoArmModel(constants.SHAPES[int(SPECS.shape_id[0])], float(SPECS.size[0]))
    adapter = UR5eArm(robot.control, robot.receive, robot.dashboard, model, clock=robot.clock)
    return {"sim_arm": SimArm(SPECS, 0), "ur5e": adapter}


def test_an_arm_state_has_the_fields_the_skill_reads():
    """An ArmState is built from exactly these fields, in this order."""
    state = ArmState(**{field: np.zeros(shape) for field, shape in SHAPES.items()})
    assert [np.shape(value) for value in state] == list(SHAPES.values())
    with pytest.raises(TypeError):
        ArmState(**{field: np.zeros(shape) for field, shape in list(SHAPES.items())[1:]})


@pytest.mark.parametrize("name", ["sim_arm", "ur5e"])
def test_every_arm_reads_the_shapes_frames_and_units_arm_py_states(name):
    """Finite float64 arrays of the stated shapes; rotations proper (R R^T = I, det +1, to
    1e-9); H symmetric positive definite; the period between commands 2 ms (500 Hz)."""
    arm = _arms()[name]
    assert arm.period == pytest.approx(constants.TIMESTEP, abs=1e-12)
    state = arm.read()
    for field, shape in SHAPES.items():
        value = np.asarray(getattr(state, field))
        assert value.shape == shape and value.dtype == np.float64, field
        assert np.all(np.isfinite(value)), field
    for rot in (state.tcp_rot, state.ft_rot):
        np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-9)
        assert np.linalg.det(rot) == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(state.mass, state.mass.T, atol=1e-12)
    assert np.linalg.eigvalsh(state.mass).min() > 0.0
    arm.hold()


def test_both_arms_read_the_same_set_up_alike():
    """The same trial's first reading: joints, tcp, Jacobian and H within 1e-9, the tool
    pointing down (tcp z along world -z within 1e-3). The F/T frame: the simulated arm's sensor
    sits on the flange, PEG_LENGTH above the tip along the tool axis; the adapter reports ur_rtde's
    tcp wrench, its sensor at the tcp with the tcp's orientation."""
    arms = _arms()
    sim, ur5e = (arms[name].read() for name in ("sim_arm", "ur5e"))
    for field in ("q", "qd", "tcp_pos", "tcp_rot", "jac", "mass"):
        np.testing.assert_allclose(getattr(ur5e, field), getattr(sim, field), atol=1e-9,
                                   err_msg=field)  # fmt: skip
    assert sim.tcp_rot[:, 2] @ np.array([0.0, 0.0, -1.0]) > 1.0 - 1e-3
    np.testing.assert_allclose(sim.ft_pos, sim.tcp_pos - constants.PEG_LENGTH * sim.tcp_rot[:, 2],
                               atol=1e-9)  # fmt: skip
    np.testing.assert_array_equal(ur5e.ft_pos, ur5e.tcp_pos)
    np.testing.assert_array_equal(ur5e.ft_rot, ur5e.tcp_rot)
