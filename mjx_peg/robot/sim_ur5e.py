"""A simulated UR5e behind ur_rtde's interface: `UR5eArm` tested, and rehearsed, without hardware.

`SimulatedUR5e(sim_arm)` plays the robot controller for a `SimArm` trial and hands out three
objects with the method names, arguments, units and frames of ur_rtde 1.6 (the signatures its
Python bindings document; only what the adapter calls):

    RTDEControlInterface(hostname, frequency)   initPeriod() -> timedelta, waitPeriod(timedelta),
        directTorque(torque, viscous_scale, coulomb_scale) -> bool, stopJ(a=2.0),
        moveJ(q, speed=1.05, acceleration=1.4) -> bool, zeroFtSensor() -> bool,
        getTCPOffset() -> [x, y, z, rx, ry, rz], setWatchdog(min_frequency=10.0) -> bool,
        kickWatchdog() -> bool, getMassMatrix(q=[], include_rotors_inertia=False) -> 36 floats
        (column by column), getCoriolisAndCentrifugalTorques(q=[], qd=[]) -> 6 floats,
        isConnected(), stopScript(), disconnect()
    RTDEReceiveInterface(hostname, frequency)   getActualQ(), getActualQd() (rad, rad/s),
        getActualTCPPose() -> [x, y, z, rx, ry, rz] (m, rotation vector, base frame),
        getActualTCPForce() -> [Fx, Fy, Fz, Mx, My, Mz] (the external wrench on the tool, base
        frame, moment about the tcp, payload compensated), getTimestamp() (s),
        getRobotMode(), getSafetyMode(), isProtectiveStopped(), isEmergencyStopped(),
        getPayload() (kg), getPayloadCog() (m, flange frame), isConnected(), disconnect()
    DashboardClient(hostname)                   connect(timeout_ms=2000), isInRemoteControl(),
        polyscopeVersion(), isConnected(), disconnect()

`directTorque` adds the controller's gravity compensation, as the UR5e does, computed from the
trial's own model; one call advances the simulation by one 2 ms period, and a period that ends
without one is held (position control). `fault(kind, at)` makes the robot misbehave from command
period `at` on: "protective_stop", "disconnect", "overload" (an extra tool force), "nan", "late"
(a period's work overruns) or "pose_offset" (the robot reports another tcp pose).
`realtime=True` paces the periods on the wall clock, as `waitPeriod` does on a robot.
"""

from __future__ import annotations

import datetime
import time

import mujoco
import numpy as np

from mjx_peg.errors import UsageError
from mjx_peg.robot.arm_model import gravity_torque
from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.world import constants

FAULTS = ("protective_stop", "disconnect", "overload", "nan", "late", "pose_offset")


class SimulatedUR5e:
    """The controller of a simulated UR5e; `.control`, `.receive`, `.dashboard` are its three
    ur_rtde interfaces."""

    def __init__(
        self,
        sim: SimArm,
        payload_mass: float = constants.PEG_MASS,
        payload_cog=(0.0, 0.0, constants.PEG_LENGTH / 2),
        tcp_offset=(0.0, 0.0, constants.PEG_LENGTH, 0.0, 0.0, 0.0),
        robot_mode: int = 7,
        safety_mode: int = 1,
        remote_control: bool = True,
        polyscope: str = "URSoftware 5.23.0.1234 (Jul 01 2025)",
        realtime: bool = False,
    ):
        if sim.command_steps != 1:
            raise UsageError("the simulated UR5e takes direct torques at 500 Hz: command_steps=1")
        self.sim = sim
        self.payload_mass, self.payload_cog = float(payload_mass), list(payload_cog)
        self.tcp_offset = [float(v) for v in tcp_offset]
        self.robot_mode, self.safety_mode = robot_mode, safety_mode
        self.remote_control, self.polyscope = remote_control, polyscope
        self.realtime = realtime
        self.cycle = 0  # command periods so far
        self.commands: list[np.ndarray] = []  # every directTorque's torque (N m)
        self.holding = False  # after stopJ
        self.connected = True
        self.faults: dict[str, tuple[int, float]] = {}
        self.lateness = 0.0  # s the simulated clock has run ahead of the physics
        self._scratch = mujoco.MjData(sim.model)
        self._reading = None
        self._commanded = False  # a directTorque in the open period
        self._period_steps = sim.steps  # physics steps when the open period began
        self.control, self.receive, self.dashboard = (
            _Control(self),
            _Receive(self),
            _Dashboard(self),
        )

    def fault(self, kind: str, at: int, value: float = 0.0, every: int = 1) -> None:
        """Misbehave from command period `at` on, in every `every`-th period (see the module
        docstring)."""
        if kind not in FAULTS:
            raise UsageError(f"unknown fault {kind!r}: choose from {', '.join(FAULTS)}")
        self.faults[kind] = (at, value, every)

    def _active(self, kind: str) -> float | None:
        at, value, every = self.faults.get(kind, (None, 0.0, 1))
        on = at is not None and self.cycle >= at and (self.cycle - at) % every == 0
        return value if on else None

    def clock(self) -> float:
        """s: the wall clock when real-time, else the simulated time at the open period's start
        plus any lateness (the controller's work takes no simulated time)."""
        if self.realtime:
            return time.perf_counter()
        return self._period_steps * float(self.sim.model.opt.timestep) + self.lateness

    def _check_link(self) -> None:
        if not self.connected or self._active("disconnect") is not None:
            self.connected = False
            raise RuntimeError("RTDE receive: connection reset by peer")

    def reading(self):
        """The current period's `ArmState` of the simulated arm (read once per period)."""
        self._check_link()
        if self._reading is None:
            self._reading = self.sim.read()
            late = self._active("late")
            if late is not None:
                self.lateness += late
        return self._reading

    def ur_wrench(self) -> np.ndarray:
        """(6,) the tcp wrench as ur_rtde reports it, from the simulated F/T reading."""
        s = self.reading()
        rest = self.sim.rest_reading
        f = s.ft_rot @ (rest[:3] - s.force)  # external force on the peg, base frame
        lever = s.ft_pos - s.tcp_pos
        cross = [lever[1] * f[2] - lever[2] * f[1], lever[2] * f[0] - lever[0] * f[2],
                 lever[0] * f[1] - lever[1] * f[0]]  # fmt: skip
        m = s.ft_rot @ (rest[3:] - s.torque) + np.array(cross)
        extra = self._active("overload")
        if extra is not None:
            f = f + np.array([0.0, 0.0, extra])
        return np.concatenate([f, m])

    def direct_torque(self, torque) -> bool:
        self._check_link()
        if self.holding or self._commanded:
            return False
        torque = np.asarray(torque, dtype=np.float64)
        s = self.reading()
        ids = self.sim.ids
        g = gravity_torque(self.sim.model, self._scratch, ids.dof_adr, ids.qpos_adr, s.q)
        self.commands.append(torque.copy())
        self._advance(torque + g)
        self._commanded = True
        return True

    def _advance(self, ctrl) -> None:
        self.reading()
        self.sim.send(ctrl)
        self._reading = None
        self.cycle += 1

    def end_period(self) -> None:
        """A period ends: one without a command holds the arm for 2 ms."""
        if not self._commanded:
            self.sim.hold()
            self._advance(self.sim.hold_torque)
        self._commanded = False
        self._period_steps = self.sim.steps


class _Control:
    """ur_rtde's RTDEControlInterface, as far as the adapter uses it."""

    def __init__(self, robot: SimulatedUR5e):
        self.robot = robot
        self.watchdog_hz = None
        self.kicks = 0
        self.zeroed = 0

    def isConnected(self) -> bool:  # noqa: N802 (ur_rtde's names)
        return self.robot.connected and self.robot._active("disconnect") is None

    def initPeriod(self) -> datetime.timedelta:  # noqa: N802
        return datetime.timedelta(seconds=self.robot.clock())

    def waitPeriod(self, t_start: datetime.timedelta) -> None:  # noqa: N802
        r = self.robot
        if r.realtime:
            end = t_start.total_seconds() + float(r.sim.period)
            while (left := end - time.perf_counter()) > 0:
                if left > 3e-4:
                    time.sleep(left - 2e-4)
        r.end_period()

    def directTorque(self, torque, viscous_scale=None, coulomb_scale=None) -> bool:  # noqa: N802
        if len(torque) != 6:
            raise RuntimeError("directTorque needs 6 joint torques")
        return self.robot.direct_torque(torque)

    def stopJ(self, a: float = 2.0, asynchronous: bool = False) -> None:  # noqa: N802
        self.robot._check_link()
        self.robot.holding = True
        self.robot.sim.hold()

    def moveJ(self, q, speed: float = 1.05, acceleration: float = 1.4, asynchronous=False) -> bool:  # noqa: N802
        """The simulated arm starts at its trial's q0 and simulates no position-controlled
        moves: a moveJ there is a no-op, elsewhere an error."""
        here = self.robot.reading().q
        if np.abs(np.asarray(q) - here).max() > 1e-6:
            raise RuntimeError("the simulated UR5e can only moveJ to where it already is")
        return True

    def zeroFtSensor(self) -> bool:  # noqa: N802
        self.zeroed += 1
        return True

    def getTCPOffset(self) -> list[float]:  # noqa: N802
        return list(self.robot.tcp_offset)

    def setWatchdog(self, min_frequency: float = 10.0) -> bool:  # noqa: N802
        self.watchdog_hz = min_frequency
        return True

    def kickWatchdog(self) -> bool:  # noqa: N802
        self.kicks += 1
        return True

    def getMassMatrix(self, q=(), include_rotors_inertia: bool = False) -> list[float]:  # noqa: N802
        return list(self.robot.reading().mass.ravel(order="F"))

    def getCoriolisAndCentrifugalTorques(self, q=(), qd=()) -> list[float]:  # noqa: N802
        s, sim = self.robot.reading(), self.robot.sim
        g = gravity_torque(sim.model, self.robot._scratch, sim.ids.dof_adr, sim.ids.qpos_adr, s.q)
        return list(s.bias - g)

    def stopScript(self) -> None:  # noqa: N802
        pass

    def disconnect(self) -> None:
        self.robot.connected = False


class _Receive:
    """ur_rtde's RTDEReceiveInterface, as far as the adapter uses it."""

    def __init__(self, robot: SimulatedUR5e):
        self.robot = robot

    def isConnected(self) -> bool:  # noqa: N802
        return self.robot.connected and self.robot._active("disconnect") is None

    def getActualQ(self) -> list[float]:  # noqa: N802
        q = self.robot.reading().q
        return [float("nan")] * 6 if self.robot._active("nan") is not None else list(q)

    def getActualQd(self) -> list[float]:  # noqa: N802
        return list(self.robot.reading().qd)

    def getActualTCPPose(self) -> list[float]:  # noqa: N802
        s = self.robot.reading()
        pos = s.tcp_pos + np.array([self.robot._active("pose_offset") or 0.0, 0.0, 0.0])
        quat, rotvec = np.zeros(4), np.zeros(3)
        mujoco.mju_mat2Quat(quat, s.tcp_rot.ravel())
        mujoco.mju_quat2Vel(rotvec, quat, 1.0)  # the rotation vector (axis x angle)
        return list(pos) + list(rotvec)

    def getActualTCPForce(self) -> list[float]:  # noqa: N802
        return list(self.robot.ur_wrench())

    def getTimestamp(self) -> float:  # noqa: N802
        return self.robot.reading().t

    def getRobotMode(self) -> int:  # noqa: N802
        return self.robot.robot_mode

    def getSafetyMode(self) -> int:  # noqa: N802
        return 3 if self.isProtectiveStopped() else self.robot.safety_mode

    def isProtectiveStopped(self) -> bool:  # noqa: N802
        return self.robot._active("protective_stop") is not None

    def isEmergencyStopped(self) -> bool:  # noqa: N802
        return False

    def getPayload(self) -> float:  # noqa: N802
        return self.robot.payload_mass

    def getPayloadCog(self) -> list[float]:  # noqa: N802
        return list(self.robot.payload_cog)

    def disconnect(self) -> None:
        self.robot.connected = False


class _Dashboard:
    """ur_rtde's DashboardClient, as far as the adapter uses it."""

    def __init__(self, robot: SimulatedUR5e):
        self.robot = robot

    def connect(self, timeout_ms: int = 2000) -> None:
        pass

    def isConnected(self) -> bool:  # noqa: N802
        return self.robot.connected

    def isInRemoteControl(self) -> bool:  # noqa: N802
        return self.robot.remote_control

    def polyscopeVersion(self) -> str:  # noqa: N802
        return self.robot.polyscope

    def disconnect(self) -> None:
        pass
