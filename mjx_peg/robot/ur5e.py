"""A real UR5e behind the `Arm` interface, over RTDE through ur_rtde (`pip install -e ".[robot]"`).

    control, receive, dashboard = connect("192.168.1.10")
    arm = UR5eArm(control, receive, dashboard, MujocoArmModel("circle", 0.05))
    arm.check_ready()
    run = run_skill(arm, SkillRuntime(vector, hole))

Every period (500 Hz, `initPeriod`/`waitPeriod`) `read` takes q, qd, the tcp pose and the tcp
wrench from `RTDEReceiveInterface`, computes the tcp pose, Jacobian and J' q' from the DH model
(`world/kinematics.py`), checks that pose against the robot's own, and takes H and h from an
`ArmModel`; `send` commands `directTorque(u - g(q))`, since the controller adds its own gravity
compensation. Frames: ur_rtde's `getActualTCPForce` is the external wrench on the tool in the
base frame, its moment about the tcp; `ArmState` wants the load the flange exerts on the peg in a
sensor frame, so the adapter reports it in the tcp frame (orientation of the flange) with the
sensor at the tcp: force = -R_tcp^T f_ext, torque = -R_tcp^T m_ext (`ur_wrench_to_sensor`).

The arm's own safety is reflected, not duplicated blindly: `check_ready` refuses to start unless
the robot is running, in normal safety mode, in remote control, on PolyScope >= 5.23 (direct
torque control), with the peg's payload and tcp set; every read stops the skill (`UR5eStop`,
within the cycle it is seen) on a protective or emergency stop, a lost connection, a raw tool
force over the limit, a tcp outside the workspace box, a tcp pose that disagrees with the
robot's, or too many missed periods. The runtime's own checks (NaN, joint speed, the filtered
tool force) stop it as on the simulated arm. `shadow=True` reads and computes but never commands.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import re
import time
from collections.abc import Callable

import numpy as np

from mjx_peg.errors import UsageError
from mjx_peg.robot.arm import ArmState
from mjx_peg.robot.arm_model import ArmModel, ModelError
from mjx_peg.robot.runtime import SafetyStop
from mjx_peg.world import constants, kinematics

INSTALL = 'pip install -e ".[robot]"'  # brings ur-rtde
PERIOD_S = 0.002  # direct_torque must be called every 2 ms controller step (500 Hz)
MIN_POLYSCOPE = (5, 23)  # direct torque control (UR Script Manual, direct_torque)
ROBOT_MODE_RUNNING = 7  # RTDE robot_mode
SAFETY_MODES = {1: "normal", 2: "reduced", 3: "protective stop", 4: "recovery",
                5: "safeguard stop", 6: "system emergency stop", 7: "robot emergency stop",
                8: "violation", 9: "fault", 10: "validate joint id", 11: "undefined",
                12: "automatic mode safeguard stop",
                13: "three-position enabling stop"}  # fmt: skip
STOP_DECELERATION = 2.0  # rad/s^2: stopJ after the skill, the leading joint's deceleration


class RobotNotReady(UsageError):
    """The robot is not set up for the skill; nothing was commanded (one line says why)."""


class MissingExtra(UsageError):
    """ur_rtde is not installed."""


class UR5eStop(SafetyStop):
    """The adapter stopped the skill; `kind` names the stop."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind


def import_rtde():
    """(rtde_control, rtde_receive, dashboard_client) modules of ur_rtde, or MissingExtra."""
    try:
        return tuple(
            importlib.import_module(m) for m in ("rtde_control", "rtde_receive", "dashboard_client")
        )
    except ImportError as error:
        raise MissingExtra(
            f"the UR5e adapter needs ur_rtde ({error}); install it with: {INSTALL}"
        ) from None


def connect(robot_ip: str, frequency: float = 1.0 / PERIOD_S):
    """(control, receive, dashboard) interfaces to the UR5e at `robot_ip`; RobotNotReady with
    one line if it cannot be reached."""
    rtde_control, rtde_receive, dashboard_client = import_rtde()
    try:
        dashboard = dashboard_client.DashboardClient(robot_ip)
        dashboard.connect()
        receive = rtde_receive.RTDEReceiveInterface(robot_ip, frequency)
        control = rtde_control.RTDEControlInterface(robot_ip, frequency)
    except RuntimeError as error:
        raise RobotNotReady(f"cannot connect to a UR5e at {robot_ip}: {error}") from None
    return control, receive, dashboard


def polyscope_version(text: str) -> tuple[int, int] | None:
    """(major, minor) of a dashboard `polyscopeVersion()` answer ('URSoftware 5.23.0.1 (...)')."""
    found = re.search(r"(\d+)\.(\d+)\.\d+", text or "")
    return (int(found.group(1)), int(found.group(2))) if found else None


def ur_wrench_to_sensor(wrench_base, tcp_rot) -> tuple[np.ndarray, np.ndarray]:
    """(force (3,), torque (3,)): ur_rtde's tcp wrench (external, base frame, moment about the
    tcp) as `ArmState` reads it: the flange's load on the peg in the tcp frame."""
    w = np.asarray(wrench_base, dtype=np.float64)
    return -(tcp_rot.T @ w[:3]), -(tcp_rot.T @ w[3:])


def angle_to(rotvec, rot: np.ndarray) -> float:
    """rad between the rotation vector `rotvec` (UR's pose convention) and the matrix `rot`:
    the angle of R(rotvec)^T rot, with R(rotvec) by Rodrigues' formula."""
    angle = math.sqrt(float(rotvec[0] ** 2 + rotvec[1] ** 2 + rotvec[2] ** 2))
    if angle < 1e-12:
        other = np.eye(3)
    else:
        k = np.asarray(rotvec, dtype=np.float64) / angle
        skew = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        other = np.eye(3) + math.sin(angle) * skew + (1.0 - math.cos(angle)) * (skew @ skew)
    cos = (float(np.sum(other * rot)) - 1.0) / 2.0  # trace(other^T rot)
    return math.acos(min(1.0, max(-1.0, cos)))


@dataclasses.dataclass(frozen=True)
class Workspace:
    """An axis-aligned box (world = base frame, m) the tcp must stay inside."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    @classmethod
    def around(cls, x: float, y: float, top: float, half_width: float = 0.1) -> Workspace:
        """`half_width` around the hole axis, from the table top to `top` above it."""
        return cls((x - half_width, y - half_width, -0.005), (x + half_width, y + half_width, top))

    def contains(self, pos) -> bool:
        return bool(np.all(np.asarray(pos) >= self.lo) and np.all(np.asarray(pos) <= self.hi))


@dataclasses.dataclass(frozen=True)
class UR5eSettings:
    """What the robot must be set to for the skill, and the adapter's stop limits."""

    tool_length: float = constants.PEG_LENGTH  # m: the tcp offset along the flange z
    payload_mass: float = constants.PEG_MASS  # kg
    payload_cog: tuple[float, float, float] = (0.0, 0.0, constants.PEG_LENGTH / 2)  # m, flange
    payload_tolerance: float = 0.05  # kg
    cog_tolerance: float = 0.01  # m
    tcp_tolerance: float = 0.001  # m and rad: the tcp offset set on the robot
    max_tool_force: float = 150.0  # N: raw tcp force that stops the skill (the UR5e's default)
    max_pose_mismatch: tuple[float, float] = (0.002, 0.02)  # m, rad: DH tcp vs the robot's
    # Periods whose work overran 2 ms: more than this many in a row (the arm without a fresh
    # command for 8 ms), or more than this share of the periods so far (and more than 10), stop.
    max_missed_in_row: int = 3
    max_missed_share: float = 0.01


class UR5eArm:
    """The `Arm` interface over ur_rtde's control, receive and dashboard interfaces."""

    period = PERIOD_S

    def __init__(
        self,
        control,
        receive,
        dashboard,
        model: ArmModel,
        settings: UR5eSettings | None = None,
        workspace: Workspace | None = None,
        shadow: bool = False,
        friction_comp: bool = False,
        clock: Callable[[], float] = time.perf_counter,
    ):
        self.control, self.receive, self.dashboard = control, receive, dashboard
        self.model = model
        self.settings = settings or UR5eSettings()
        self.workspace = workspace
        self.shadow = shadow
        self.friction_comp = friction_comp
        self.clock = clock
        self.missed = self.missed_in_row = 0  # periods whose work overran: all, the last run
        self.commands = 0  # directTorque calls (none in shadow mode)
        self._period_start = None  # initPeriod's token of the open period
        self._work_start = None  # clock() when the open period's reading began
        self._last_read = None
        self._t0 = None
        self.log: dict[str, list] = {k: [] for k in ("t", "period_s", "work_s", "q", "ur_wrench",
                                                      "torque", "sent")}  # fmt: skip

    # -- before the first command ------------------------------------------------------------
    def check_ready(self) -> None:
        """RobotNotReady (one line) unless the robot can run the skill now."""
        s, r, c = self.settings, self.receive, self.control
        if not (r.isConnected() and c.isConnected()):
            raise RobotNotReady("the RTDE connection to the UR5e is not up")
        if not self.dashboard.isInRemoteControl():
            raise RobotNotReady(
                "the UR5e is not in remote control: set PolyScope to Remote Control (header "
                "icon) so that RTDE may command it"
            )
        version = polyscope_version(self.dashboard.polyscopeVersion())
        if version is None or version < MIN_POLYSCOPE:
            raise RobotNotReady(
                f"PolyScope {self.dashboard.polyscopeVersion()!r} has no direct torque control; "
                f"it needs {MIN_POLYSCOPE[0]}.{MIN_POLYSCOPE[1]} or later"
            )
        mode = r.getRobotMode()
        if mode != ROBOT_MODE_RUNNING:
            raise RobotNotReady(
                f"the UR5e's robot mode is {mode}, not {ROBOT_MODE_RUNNING} (running): power it "
                "on and release the brakes"
            )
        safety = r.getSafetyMode()
        if safety != 1:
            raise RobotNotReady(
                f"the UR5e's safety mode is {SAFETY_MODES.get(safety, safety)}, not normal"
            )
        mass, cog = r.getPayload(), np.asarray(r.getPayloadCog(), dtype=np.float64)
        if abs(mass - s.payload_mass) > s.payload_tolerance:
            raise RobotNotReady(
                f"the UR5e's payload is {mass:.3f} kg, the peg's is {s.payload_mass:.3f} kg: set "
                "it in the installation (Payload) so its gravity compensation carries the peg"
            )
        if np.linalg.norm(cog - s.payload_cog) > s.cog_tolerance:
            raise RobotNotReady(
                f"the UR5e's payload centre of gravity is {np.round(1000 * cog, 1)} mm, the "
                f"peg's is {np.round(1000 * np.asarray(s.payload_cog), 1)} mm"
            )
        tcp = np.asarray(c.getTCPOffset(), dtype=np.float64)
        want = np.array([0.0, 0.0, s.tool_length, 0.0, 0.0, 0.0])
        if tcp.shape != (6,) or np.abs(tcp - want).max() > s.tcp_tolerance:
            raise RobotNotReady(
                f"the UR5e's TCP offset is {np.round(tcp, 4).tolist()}, the skill's is "
                f"{want.tolist()} (x, y, z m, rotation vector): set it in the installation (TCP)"
            )

    # -- the Arm interface ---------------------------------------------------------------------
    def read(self) -> ArmState:
        if self._period_start is not None:
            self._close_period()
        self._period_start = self.control.initPeriod()
        now = self.clock()
        self.log["period_s"].append(
            math.nan if self._work_start is None else now - self._work_start
        )
        self._work_start = now
        try:
            state, wrench = self._measure()
        except (RuntimeError, OSError) as error:
            if isinstance(error, SafetyStop):
                raise
            raise UR5eStop("connection_lost", f"connection to the UR5e lost: {error}") from None
        self.log["t"].append(state.t)
        self.log["q"].append(state.q)
        self.log["ur_wrench"].append(wrench)
        self._last_read = state
        return state

    def send(self, torque: np.ndarray) -> None:
        torque = np.asarray(torque, dtype=np.float64)
        # The controller adds g(q) itself; the work of a period ends with the command ready.
        command = None if self.shadow else torque - self.model.gravity(self._last_read.q)
        self.log["torque"].append(torque.copy())
        self.log["work_s"].append(self.clock() - self._work_start)
        self.log["sent"].append(not self.shadow)
        if self.shadow:
            return
        args = [] if self.friction_comp else [[0.0] * 6, [0.0] * 6]
        try:
            ok = self.control.directTorque([float(v) for v in command], *args)
            self.control.kickWatchdog()
        except RuntimeError as error:
            raise UR5eStop("connection_lost", f"connection to the UR5e lost: {error}") from None
        if ok is False:
            raise UR5eStop("connection_lost", "the UR5e refused the torque command")
        self.commands += 1

    def hold(self) -> None:
        """Leave torque mode: the controller decelerates the joints and holds them (stopJ)."""
        if self.shadow:
            return
        try:
            self.control.stopJ(STOP_DECELERATION)
        except RuntimeError:
            pass  # the connection is gone: ur_rtde's watchdog and the robot's stops act alone

    # -- per period ----------------------------------------------------------------------------
    def _close_period(self) -> None:
        """Count a period whose work overran, stop past the bounds, then wait for the next."""
        work = self.clock() - self._work_start
        s = self.settings
        if work > self.period:
            self.missed += 1
            self.missed_in_row += 1
            periods = len(self.log["t"])
            if self.missed_in_row > s.max_missed_in_row or self.missed > max(
                10, s.max_missed_share * periods
            ):
                raise UR5eStop(
                    "missed_periods",
                    f"{self.missed} control periods overran {1000 * self.period:g} ms "
                    f"({self.missed_in_row} in a row; the last took {1000 * work:.2f} ms): the "
                    "loop cannot keep the UR5e's rate",
                )
        else:
            self.missed_in_row = 0
        self.control.waitPeriod(self._period_start)

    def _measure(self) -> tuple[ArmState, np.ndarray]:
        r, s = self.receive, self.settings
        if not (r.isConnected() and self.control.isConnected()):
            raise UR5eStop("connection_lost", "connection to the UR5e lost")
        if r.isProtectiveStopped():
            raise UR5eStop("protective_stop", "the UR5e protective-stopped")
        if r.isEmergencyStopped():
            raise UR5eStop("emergency_stop", "the UR5e is emergency-stopped")
        safety = r.getSafetyMode()
        if safety != 1:
            raise UR5eStop(
                "safety_mode",
                f"the UR5e left normal safety mode: {SAFETY_MODES.get(safety, safety)}",
            )
        q = np.asarray(r.getActualQ(), dtype=np.float64)
        qd = np.asarray(r.getActualQd(), dtype=np.float64)
        wrench = np.asarray(r.getActualTCPForce(), dtype=np.float64)
        pose = np.asarray(r.getActualTCPPose(), dtype=np.float64)
        stamp = float(r.getTimestamp())
        if self._t0 is None:
            self._t0 = stamp
        if not all(np.all(np.isfinite(v)) for v in (q, qd, wrench, pose)):
            raise UR5eStop("nan", "a reading from the UR5e is NaN or infinite")
        tcp_pos, tcp_rot, jac, jac_dot = kinematics.tcp_kinematics(q, qd, s.tool_length)
        d_pos = float(np.linalg.norm(tcp_pos - pose[:3]))
        d_rot = angle_to(pose[3:], tcp_rot)
        if d_pos > s.max_pose_mismatch[0] or d_rot > s.max_pose_mismatch[1]:
            raise UR5eStop(
                "pose_mismatch",
                f"the DH model's tcp is {1000 * d_pos:.2f} mm / {math.degrees(d_rot):.2f} deg "
                "from the robot's (wrong TCP offset, or the robot's calibration)",
            )
        if self.workspace is not None and not self.workspace.contains(pose[:3]):
            raise UR5eStop(
                "workspace",
                f"the tcp {np.round(1000 * pose[:3], 1).tolist()} mm left the workspace box "
                f"{np.round(1000 * np.asarray(self.workspace.lo), 1).tolist()} .. "
                f"{np.round(1000 * np.asarray(self.workspace.hi), 1).tolist()} mm",
            )
        tool_force = float(np.linalg.norm(wrench[:3]))
        if tool_force > s.max_tool_force:
            raise UR5eStop(
                "overload", f"tool force {tool_force:.0f} N beyond {s.max_tool_force:.0f} N"
            )
        try:
            mass, bias = self.model.dynamics(q, qd)
        except ModelError as error:
            raise UR5eStop("model", str(error)) from None
        force, torque = ur_wrench_to_sensor(wrench, tcp_rot)
        state = ArmState(
            t=stamp - self._t0,
            q=q,
            qd=qd,
            tcp_pos=tcp_pos,
            tcp_rot=tcp_rot,
            jac=jac,
            jac_dot=jac_dot,
            mass=mass,
            bias=bias,
            force=force,
            torque=torque,
            ft_pos=tcp_pos.copy(),
            ft_rot=tcp_rot.copy(),
        )
        return state, wrench

    def close(self) -> None:
        """End the RTDE script and disconnect (after `hold`)."""
        for call in (self.control.stopScript, self.control.disconnect, self.receive.disconnect):
            try:
                call()
            except RuntimeError:
                pass
