"""robot/sim_ur5e.py: the simulated UR5e speaks ur_rtde's interface (names, parameters, units,
frames) for a SimArm trial, and adds the controller's gravity compensation to direct torques."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.robot.sim_ur5e import SimulatedUR5e
from mjx_peg.robot.ur5e import import_rtde
from mjx_peg.world.rotations import matrix_from_rotvec
from mjx_peg.world.task import TaskConfig, sample_trials

SPECS = sample_trials(TaskConfig(shapes=("circle",), linear_error=0.002, angular_error=0.0), 0, 1)


def test_the_simulated_ur5e_follows_ur_rtdes_signatures():
    """Every method the adapter calls on the simulated robot exists in ur_rtde with that name,
    and the simulated one accepts ur_rtde's parameters by position."""
    rtde_control, rtde_receive, dashboard_client = import_rtde()
    robot = SimulatedUR5e(SimArm(SPECS, 0))
    pairs = [(robot.control, rtde_control.RTDEControlInterface),
             (robot.receive, rtde_receive.RTDEReceiveInterface),
             (robot.dashboard, dashboard_client.DashboardClient)]  # fmt: skip
    for fake, real in pairs:
        for name, method in inspect.getmembers(type(fake), inspect.isfunction):
            if name.startswith("_"):
                continue
            assert hasattr(real, name), f"{real.__name__} has no {name}"
            doc = getattr(real, name).__doc__ or ""
            wanted = re_params(doc, real.__name__, name)
            got = list(inspect.signature(method).parameters)[1:]
            assert len(got) >= len(wanted), (name, wanted, got)


def re_params(doc: str, cls: str, name: str) -> list[str]:
    """Parameter names of `name` from a pybind11 signature line 'name(self: cls, a: T = v, ...)'."""
    first = next(line for line in doc.splitlines() if line.strip().startswith(f"{name}("))
    inner = first[first.index("(") + 1 : first.rindex(")")]
    params = [p.split(":")[0].strip() for p in inner.split(", ") if ":" in p]
    return [p for p in params if p != "self"]


def test_the_robot_reports_the_simulated_arm_in_ur_rtdes_units_and_frames():
    """q, qd and the timestamp as read; the tcp pose as position and rotation vector; the mass
    matrix column by column; the Coriolis torques without gravity, which the robot adds."""
    sim = SimArm(SPECS, 0)
    robot = SimulatedUR5e(sim)
    state = robot.reading()
    control, receive = robot.control, robot.receive
    np.testing.assert_array_equal(receive.getActualQ(), state.q)
    np.testing.assert_array_equal(receive.getActualQd(), state.qd)
    assert receive.getTimestamp() == state.t == 0.0
    pose = np.array(receive.getActualTCPPose())
    np.testing.assert_allclose(pose[:3], state.tcp_pos, atol=1e-15)
    np.testing.assert_allclose(matrix_from_rotvec(pose[3:]), state.tcp_rot, atol=1e-12)
    mass = np.array(control.getMassMatrix(list(state.q), True)).reshape(6, 6, order="F")
    np.testing.assert_array_equal(mass, state.mass)
    coriolis = control.getCoriolisAndCentrifugalTorques(list(state.q), list(state.qd))
    np.testing.assert_allclose(coriolis, np.zeros(6), atol=1e-9)  # at rest: gravity only


def test_a_zero_direct_torque_holds_the_arm_by_the_robots_gravity_compensation():
    """directTorque(0) sends only the gravity the robot adds: the arm stays within 1e-6 rad for
    0.1 s; without it (holding nothing) it falls."""
    robot = SimulatedUR5e(SimArm(SPECS, 0))
    q0 = np.array(robot.receive.getActualQ())
    for _ in range(50):
        t = robot.control.initPeriod()
        assert robot.control.directTorque([0.0] * 6, 0.0, 0.0)
        robot.control.waitPeriod(t)
    assert robot.cycle == len(robot.commands) == 50
    assert np.abs(np.array(robot.receive.getActualQ()) - q0).max() < 1e-6
    falling = SimArm(SPECS, 0)
    for _ in range(50):
        falling.read()
        falling.send(np.zeros(6))
    assert np.abs(falling.read().q - q0).max() > 1e-3


def test_the_simulated_robot_refuses_what_it_cannot_simulate():
    with pytest.raises(ValueError, match="takes direct torques at 500 Hz"):
        SimulatedUR5e(SimArm(SPECS, 0, command_steps=4))
    robot = SimulatedUR5e(SimArm(SPECS, 0))
    with pytest.raises(ValueError, match="unknown fault 'smoke'"):
        robot.fault("smoke", at=3)
    with pytest.raises(RuntimeError, match="can only moveJ to where it already is"):
        robot.control.moveJ([0.0] * 6)
    assert robot.control.moveJ(robot.receive.getActualQ())
