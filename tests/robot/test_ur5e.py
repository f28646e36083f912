"""The UR5e adapter (`robot/ur5e.py`) against the simulated UR5e behind ur_rtde's interface: the
same trial as on the simulated arm, units and frames, every stop within one cycle, shadow mode,
the robot's settings, the CLI's real-arm path and its bad input."""

from __future__ import annotations

import inspect
import subprocess
import sys

import numpy as np
import pytest

from mjx_peg.engines.trial import TrialConfig
from mjx_peg.robot import cli
from mjx_peg.robot.arm_model import ControllerArmModel, MujocoArmModel
from mjx_peg.robot.runtime import HoleEstimate, SkillRuntime, run_skill
from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.robot.sim_ur5e import SimulatedUR5e
from mjx_peg.robot.ur5e import (
    RobotNotReady,
    UR5eArm,
    UR5eSettings,
    Workspace,
    import_rtde,
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


def test_the_simulated_ur5e_follows_ur_rtdes_signatures():
    """Every method the adapter calls on the simulated robot exists in ur_rtde with that name,
    and the simulated one accepts ur_rtde's parameters by position."""
    rtde_control, rtde_receive, dashboard_client = import_rtde()
    robot = SimulatedUR5e(SimArm(_specs(n=1), 0))
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


def test_cli_rehearsal_inserts_and_writes_its_log(tmp_path, capsys):
    argv = ["--rehearse", "--hole", "450,-120,30", "--shape", "square", "--time-limit", "5",
            "--out", str(tmp_path)]  # fmt: skip
    assert cli.main(argv) == 0
    out = capsys.readouterr().out
    assert "baseline on the UR5e at sim" in out and "inserted at" in out
    rows = (tmp_path / "ur5e_run.csv").read_text().splitlines()
    header = rows[0].split(",")
    assert header[:3] == ["t_s", "period_ms", "work_ms"] and header[-1] == "sent"
    assert "wrench_fz" in header and "goal_z" in header and "tau6" in header
    assert 200 < len(rows) - 1 < 2500
    assert (tmp_path / "ur5e_run.png").stat().st_size > 10_000
    assert cli.main(argv) == 2  # an earlier run is kept without --force
    assert "--force" in capsys.readouterr().err


def test_cli_dry_run_prints_the_plan_and_connects_to_nothing(capsys):
    assert cli.main(["--dry-run", "--hole", "450,-120,30", "--shape", "circle"]) == 0
    out = capsys.readouterr().out
    assert "move (moveJ) to the start (450.0, -120.0, 140.0) mm" in out
    assert "t =  2.00 s  tcp (450.0, -120.0, -0.0) mm" in out or "-120.0, 0.0) mm" in out
    assert "nothing was connected or moved" in out


@pytest.mark.parametrize(
    "argv, message",
    [
        (
            ["--robot-ip", "127.0.0.1", "--hole", "450,-120,30"],
            "cannot connect to a UR5e at 127.0.0.1",
        ),
        (["--robot-ip", "not an ip!", "--hole", "1,2,3"], "not an IP address or host name"),
        (["--robot-ip", "127.0.0.1"], "need --hole X,Y,YAW"),
        (["--dry-run", "--hole", "450,-120"], "--hole must be X,Y,YAW"),
        (["--dry-run", "--hole", "2000,0,0"], "out of the UR5e's reach"),
        (["--shadow", "--hole", "450,0,0"], "need --robot-ip, --rehearse or --dry-run"),
        (["--rehearse", "--robot-ip", "127.0.0.1", "--hole", "450,0,0"], "drop --robot-ip"),
        (["--robot-ip", "127.0.0.1", "--hole", "450,0,0", "--command-hz", "125"], "500 Hz only"),
    ],
)
def test_cli_real_arm_bad_input_is_one_line(argv, message, tmp_path, capsys):
    code = cli.main([*argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and message in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "out").exists()  # nothing written before the input is accepted


@pytest.mark.parametrize(
    "mode",
    [
        ["--dry-run"],
        ["--rehearse"],
        ["--shadow", "--robot-ip", "127.0.0.1"],
        ["--robot-ip", "127.0.0.1"],
    ],  # fmt: skip
)
@pytest.mark.parametrize(
    "policy, part, message",
    [
        (
            "transfer",
            ["--shape", "circle"],
            "--policy transfer was trained on triangle, not circle",
        ),
        ("paper", ["--shape", "triangle"], "was trained on circle, square, not triangle"),
        ("paper", ["--shape", "circle", "--size", "25"], "trained at S = 50 mm, not 25 mm"),
    ],
)
def test_cli_refuses_a_shipped_policy_on_a_part_it_was_not_trained_for(
    mode, policy, part, message, tmp_path, capsys
):
    """The shipped manifests as written (config.shapes, config.size_mm), on every real-arm
    path, before a plan is printed, a connection tried or anything written."""
    argv = [*mode, "--policy", policy, *part, "--hole", "450,-120,30"]
    assert cli.main([*argv, "--out", str(tmp_path / "out")]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and message in captured.err and len(captured.err.splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_cli_runs_a_shipped_policy_on_the_part_it_was_trained_for(capsys):
    argv = ["--dry-run", "--policy", "transfer", "--shape", "triangle", "--hole", "450,-120,30"]
    assert cli.main(argv) == 0
    assert "nothing was connected or moved" in capsys.readouterr().out


@pytest.mark.parametrize("mode", [[], ["--rehearse", "--hole", "450,-120,30"]])
def test_cli_never_writes_into_the_folder_of_the_policy_it_reads(
    mode, tmp_path, monkeypatch, capsys
):
    """--out is compared with --policy as resolved folders: a shipped policy's name, a link to
    its folder and a relative path to it are all the same folder."""
    import shutil

    from mjx_peg.policy import shipped

    copy = tmp_path / "policies"
    shutil.copytree(shipped.SHIPPED_DIR / "paper", copy / "paper")
    monkeypatch.setattr(shipped, "SHIPPED_DIR", copy)
    (tmp_path / "link").symlink_to(copy / "paper")
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in (copy / "paper").iterdir())
    for out in ("link", "policies/paper", str(copy / "paper"), "policies"):
        argv = [*mode, "--policy", "paper", "--shape", "circle", "--trials", "1", "--out", out]
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert "an output never replaces an input" in err and len(err.splitlines()) == 1, err
    assert sorted(p.name for p in (copy / "paper").iterdir()) == before


def test_without_ur_rtde_the_package_imports_and_the_cli_says_how_to_install(tmp_path):
    code = (
        "import sys\n"
        "for m in ('rtde_control', 'rtde_receive', 'dashboard_client'):\n"
        "    sys.modules[m] = None\n"
        "import mjx_peg.robot.ur5e, mjx_peg.robot.runtime\n"
        "from mjx_peg.robot import cli\n"
        "argv = ['--robot-ip', '127.0.0.1', '--hole', '450,0,0', '--out', sys.argv[1]]\n"
        "sys.exit(cli.main(argv))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True
    )
    assert done.returncode == 2, done.stderr
    assert 'pip install -e ".[robot]"' in done.stderr and len(done.stderr.splitlines()) == 1
