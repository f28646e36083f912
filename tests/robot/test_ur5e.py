"""The UR5e adapter (`robot/ur5e.py`) against the simulated UR5e behind ur_rtde's interface: the
same trial as on the simulated arm, units and frames, every stop within one cycle, shadow mode,
the robot's settings and its model refused."""

from __future__ import annotations

import numpy as np
import pytest

from mjx_peg.engines.trial import TrialConfig
from mjx_peg.robot.arm_model import ControllerArmModel, MujocoArmModel
from mjx_peg.robot.runtime import HoleEstimate, SkillRuntime, run_skill
from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.robot.sim_ur5e import SimulatedUR5e
from mjx_peg.robot.ur5e import (
    RobotNotReady,
    UR5eArm,
    UR5eSettings,
    Workspace,
    polyscope_version,
)
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.control_step import wrench_in_goal_frame
from mjx_peg.world import constants
from mjx_peg.world.rotations import tool_down_rotation
from mjx_peg.world.task import TaskConfig, sample_trials

SHORT = TrialConfig(time_limit_s=4.0)


def _specs(shape="circle", n=2, linear_mm=2.0):
    """Trials with localization errors and no grasp error (the adapter's model of the arm has
    the peg at its nominal grasp; a grasp error is a model error the simulated arm would not
    share)."""
    task = TaskConfig(shapes=(shape,), linear_error=linear_mm / 1000.0, angular_error=0.0,
                      grasp_model="flange")  # fmt: skip
    specs = sample_trials(task, 0, n)
    specs.grasp_error[:] = 0.0
    return specs


def _adapter(specs, i=0, **kwargs):
    sim = SimArm(specs, i)
    robot = SimulatedUR5e(sim)
    model = MujocoArmModel(constants.SHAPES[int(specs.shape_id[i])], float(specs.size[i]))
    arm = UR5eArm(robot.control, robot.receive, robot.dashboard, model, clock=robot.clock, **kwargs)
    return robot, sim, arm


def _run(specs, arm, sim, i=0, config=SHORT):
    runtime = SkillRuntime(baseline_params(), HoleEstimate.of_trial(specs, i), config)
    return run_skill(arm, runtime, done=lambda state: sim.inserted())


def test_a_trial_through_the_adapter_is_the_simulated_arms_trial():
    """Through UR5eArm (DH kinematics, the model's H and h, u - g sent and the controller's g
    added back, the wrench through ur_rtde's base-frame convention) a trial ends as on SimArm
    directly: same outcome and time, the tip within 1e-9 m (measured: ~1e-13 m)."""
    specs = _specs()
    for i in range(len(specs)):
        direct = SimArm(specs, i)
        expected = _run(specs, direct, direct, i)
        robot, sim, arm = _adapter(specs, i)
        arm.check_ready()
        got = _run(specs, arm, sim, i)
        assert expected.success and got.success
        assert got.time_s == expected.time_s and got.commands == expected.commands
        assert np.abs(sim.tip_pos() - direct.tip_pos()).max() < 1e-9
        np.testing.assert_allclose(got.log["tcp_pos"], expected.log["tcp_pos"], rtol=0, atol=1e-9)
        assert len(robot.commands) == got.commands == arm.commands and arm.missed == 0


def test_a_base_frame_tcp_force_arrives_as_the_runtimes_wrench():
    """A wrench ur_rtde reports (external, base frame, moment about the tcp) reaches the
    compliance as the same wrench in the goal frame, with the tcp tilted off the goal."""

    class Receive:
        wrench = [0.0] * 6

        def __getattr__(self, name):
            return {"isConnected": lambda: True, "isProtectiveStopped": lambda: False,
                    "isEmergencyStopped": lambda: False, "getSafetyMode": lambda: 1,
                    "getActualQ": lambda: list(q), "getActualQd": lambda: [0.0] * 6,
                    "getActualTCPForce": lambda: list(self.wrench), "getTimestamp": lambda: 0.0,
                    "getActualTCPPose": lambda: pose}[name]  # fmt: skip

    class Control:
        def initPeriod(self):  # noqa: N802
            return 0.0

        def waitPeriod(self, t):  # noqa: N802
            pass

        def isConnected(self):  # noqa: N802
            return True

    q = np.array([0.3, -1.4, 1.9, -2.2, -1.3, 0.4])
    from mjx_peg.world.kinematics import fk_tcp
    from mjx_peg.world.rotations import rotvec_from_matrix

    pos, rot = fk_tcp(q, constants.PEG_LENGTH)
    pose = list(pos) + list(rotvec_from_matrix(rot))
    receive = Receive()
    arm = UR5eArm(Control(), receive, None, MujocoArmModel("square", 0.05))
    rest = arm.read()
    receive.wrench = [3.0, -7.0, 25.0, 0.4, -0.2, 0.1]
    loaded = arm.read()
    goal_rot = tool_down_rotation(np.array(0.7))
    tare = np.concatenate([rest.force, rest.torque])
    got = wrench_in_goal_frame(loaded.force, loaded.torque, tare, loaded.ft_rot,
                               loaded.ft_pos - loaded.tcp_pos, goal_rot)  # fmt: skip
    w = np.array(receive.wrench)
    np.testing.assert_allclose(got, np.concatenate([goal_rot.T @ w[:3], goal_rot.T @ w[3:]]),
                               atol=1e-12)  # fmt: skip
    assert not np.allclose(rot, goal_rot, atol=0.05)  # the frames differ: the test can tell


@pytest.mark.parametrize(
    "kind, value, message",
    [
        ("protective_stop", 0.0, "the UR5e protective-stopped"),
        ("disconnect", 0.0, "connection to the UR5e lost"),
        ("overload", 400.0, "tool force"),
        ("nan", 0.0, "NaN or infinite"),
        ("pose_offset", 0.005, "from the robot's"),
    ],
)
def test_each_stop_acts_in_the_cycle_it_is_seen(kind, value, message):
    robot, sim, arm = _adapter(_specs(n=1))
    robot.fault(kind, at=100, value=value)
    run = _run(_specs(n=1), arm, sim)
    assert message in run.stopped and not run.success
    assert run.commands == len(robot.commands) == 100  # nothing sent from the faulty cycle on
    assert robot.holding == (kind != "disconnect")  # held, unless there is no link to hold with


def test_missed_periods_stop_the_arm_past_the_bounds():
    """More than 3 overruns in a row stop the arm; isolated ones are counted, and stop it past
    1 % of the periods (and 10)."""
    robot, sim, arm = _adapter(_specs(n=1))
    robot.fault("late", at=100, value=0.003)  # from period 100 every period overruns by 1 ms
    run = _run(_specs(n=1), arm, sim)
    assert "4 control periods overran 2 ms (4 in a row" in run.stopped
    assert run.commands == 104 and arm.missed == 4 and robot.holding

    robot, sim, arm = _adapter(_specs(n=1), settings=UR5eSettings(max_missed_share=0.0))
    robot.fault("late", at=20, value=0.003, every=20)  # every 20th period overruns, alone
    run = _run(_specs(n=1), arm, sim)
    assert "11 control periods overran 2 ms (1 in a row" in run.stopped
    assert arm.missed == 11 and 200 < run.commands < 240


def test_leaving_the_workspace_box_stops_the_arm():
    specs = _specs(n=1)
    robot, sim, arm = _adapter(specs)
    start_z = float(specs.tcp0_pos[0, 2])
    x, y = specs.hole_est_pos[0]
    arm.workspace = Workspace((x - 0.1, y - 0.1, start_z - 0.02), (x + 0.1, y + 0.1, start_z + 0.1))
    run = _run(specs, arm, sim)
    assert "left the workspace box" in run.stopped and robot.holding
    z = run.log["tcp_pos"][:, 2]
    assert z.min() >= start_z - 0.02 and sim.data.site_xpos[sim.ids.tcp_site][2] < start_z - 0.02
    assert run.commands == len(robot.commands)


def test_shadow_mode_sends_nothing():
    robot, sim, arm = _adapter(_specs(n=1), shadow=True)
    q0 = sim.data.qpos[sim.ids.qpos_adr].copy()
    run = _run(_specs(n=1), arm, sim, config=TrialConfig(time_limit_s=0.5))
    assert robot.commands == [] and arm.commands == 0 and not robot.holding
    assert run.commands == 250 and len(arm.log["torque"]) == 250  # computed and logged
    assert np.abs(np.asarray(arm.log["torque"])).max() > 1.0
    assert not any(arm.log["sent"])
    assert np.abs(sim.data.qpos[sim.ids.qpos_adr] - q0).max() < 1e-3  # the arm stayed


@pytest.mark.parametrize(
    "change, message",
    [
        ({"remote_control": False}, "not in remote control"),
        ({"polyscope": "URSoftware 5.22.1.0 (Jan 2025)"}, "has no direct torque control"),
        ({"robot_mode": 5}, "robot mode is 5, not 7"),
        ({"safety_mode": 2}, "safety mode is reduced"),
        ({"payload_mass": 1.2}, "payload is 1.200 kg, the peg's is 0.300 kg"),
        ({"payload_cog": (0.0, 0.0, 0.0)}, "payload centre of gravity"),
        ({"tcp_offset": (0, 0, 0.1, 0, 0, 0)}, "TCP offset is"),
    ],
)
def test_a_robot_not_set_up_for_the_skill_is_refused(change, message):
    specs = _specs(n=1)
    robot = SimulatedUR5e(SimArm(specs, 0), **change)
    arm = UR5eArm(robot.control, robot.receive, robot.dashboard, MujocoArmModel("circle", 0.05))
    with pytest.raises(RobotNotReady, match=message):
        arm.check_ready()
    assert robot.commands == [] and robot.cycle == 0


def test_polyscope_versions_parse():
    assert polyscope_version("URSoftware 5.23.0.1234 (Jul 01 2025)") == (5, 23)
    assert polyscope_version("URSoftware 10.10.0.12 (x)") == (10, 10)
    assert polyscope_version("garbage") is None


def test_the_controllers_model_is_used_when_sane_and_refused_when_not():
    specs = _specs(n=1)
    robot, sim, _ = _adapter(specs)
    model = ControllerArmModel(robot.control)
    state = robot.reading()
    mass, bias = model.dynamics(state.q, state.qd)
    np.testing.assert_allclose(mass, state.mass, atol=1e-12)
    arm = UR5eArm(robot.control, robot.receive, robot.dashboard, model, clock=robot.clock)
    robot.control.getMassMatrix = lambda q, rotors: [0.0] * 36  # a version that answers zeros
    run = _run(specs, arm, sim)
    assert "diagonal" in run.stopped and run.commands == 0
