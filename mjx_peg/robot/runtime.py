"""The learned skill as a control loop: hole estimate -> 38 numbers -> torques, every period.

    runtime = SkillRuntime(controller_vector("runs/paper", hole), hole)
    run = run_skill(arm, runtime, time_limit_s=60.0)

`SkillRuntime` holds one insertion: the goal from the estimated hole (as in `task.goal_pose`),
the tare and the DMP's start taken at the first reading, then, on each reading, the F/T sensor's
software filter (`sensor.filter_step`, the nominal cutoff of `TrialConfig.sensor`), the compliance
damping's low-pass and `control_step.skill_torque`. It stops the skill (`SafetyStop`) on a
non-finite measurement or torque, a joint faster than `TrialConfig.max_joint_speed` (twice the
UR5e's 180 deg/s, where the real arm would protective-stop; the engines count such a trial as
failed, `unstable`), a sensed tool force beyond `TrialConfig.max_tool_force` (the UR5e's
protective stop; checked at the next reading, as the engines do, which flag it `protective_stop`)
or a clock that runs backwards, and `run_skill` stops a skill that has settled
(`TrialConfig.end_settled`: at rest or repeating the same motion, the wrench the compliance sees
included, it cannot insert any more; a failure, as the engines end it, stopped "settled"). The
math runs on arrays with a leading batch dimension of 1, the engines' code path: on the simulated
arm at 500 Hz a run follows the engine's trial to 1e-12 m in free motion and ends as it does (the
wrench can differ from the engine's in the last bit, which contact can amplify;
tests/robot/test_runtime.py).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from mjx_peg.engines.trial import (
    TrialConfig,
    as_controller_params,
    control_config,
    fitted_basis,
    is_settled,
    settle_start,
    settle_update,
)
from mjx_peg.errors import UsageError
from mjx_peg.policy import observation
from mjx_peg.policy.export import Policy, load_policy
from mjx_peg.robot.arm import Arm, ArmState
from mjx_peg.skill import sensor
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.control_step import (
    Measurement,
    external_wrench,
    make_skill,
    skill_torque,
    start_state,
    wrench_to_goal,
)
from mjx_peg.skill.params import ControllerParams
from mjx_peg.skill.search import aligned_rotation, spiral_state
from mjx_peg.world import constants
from mjx_peg.world.task import goal_pose


class SafetyStop(RuntimeError):
    """The skill must stop now (one line says why)."""


@dataclasses.dataclass(frozen=True)
class HoleEstimate:
    """Where the skill believes the hole is: centre x, y (m), yaw (rad), shape, size S (m)."""

    x: float
    y: float
    yaw: float
    shape: str
    size: float

    def __post_init__(self):
        if self.shape not in constants.SHAPES:
            raise UsageError(f"hole shape must be one of {constants.SHAPES}, got {self.shape!r}")
        for name in ("x", "y", "yaw", "size"):
            if not math.isfinite(getattr(self, name)):
                raise UsageError(
                    f"hole {name} must be a finite number, got {getattr(self, name)!r}"
                )
        if self.size <= 0:
            raise UsageError(f"hole size must be positive (m), got {self.size!r}")

    @classmethod
    def of_trial(cls, specs, index: int) -> HoleEstimate:
        """The estimate of trial `index` of a `TrialSpec` (its hole_est_pos/yaw, shape, size)."""
        x, y = (float(v) for v in specs.hole_est_pos[index])
        shape = constants.SHAPES[int(specs.shape_id[index])]
        return cls(x, y, float(specs.hole_est_yaw[index]), shape, float(specs.size[index]))

    def observation(self) -> np.ndarray:
        """(1, 8) policy observation of this estimate."""
        return observation.observe(
            np.array([constants.SHAPES.index(self.shape)]),
            np.array([self.size]),
            np.array([[self.x, self.y]]),
            np.array([self.yaw]),
        )


def controller_vector(policy: str | Policy, hole: HoleEstimate) -> np.ndarray:
    """(38,) controller numbers for `hole` from a loaded `Policy`, a run directory holding
    policy.npz, or 'baseline'."""
    if isinstance(policy, str):
        if policy == "baseline":
            return baseline_params()
        policy = load_policy(policy)
    return policy.vectors_for(hole.observation())[0]


class SkillRuntime:
    """One insertion with fixed controller numbers; `start` at the first reading, then `torque`."""

    def __init__(self, vector, hole: HoleEstimate, config: TrialConfig | None = None):
        self.config = cfg = config or TrialConfig()
        p = as_controller_params(vector, 1)
        self.params = ControllerParams(p.k_t[0], p.k_theta[0], p.compliance[0])
        self.hole = hole
        self.basis = fitted_basis(cfg.movement)
        self.goal_pos, self.goal_rot = goal_pose(np.array([[hole.x, hole.y]]), np.array([hole.yaw]))
        self.control = control_config(cfg)
        self.skill = None
        self.tare = np.zeros((1, 6))
        self.t0 = self.last_t = 0.0
        self.wrench = np.zeros(6)  # the last wrench the compliance saw (goal frame)
        # The sensor's software filter and the compliance damping (their states), the last
        # sensed tool force.
        self.alpha = np.array([math.exp(-2.0 * math.pi * cfg.timestep * cfg.sensor.cutoff_hz)])
        self.filtered = np.zeros((1, 6))
        self.coupled = np.zeros((1, 6))
        self.aligned = np.zeros((1, 3))  # the goal's rotation the search's alignment found (rad)
        self.spiral = np.zeros((1, 3))  # the search's spiral state (search.spiral_state)
        self.tool_force = self.peak_force = 0.0  # N: the last and the largest sensed force
        self.settle = settle_start((1,))
        self.period_steps = 1  # physics steps (TrialConfig.timestep) per command; run_skill sets

    def start(self, state: ArmState) -> None:
        """Tare the F/T reading, take the DMP's start y0 from the tcp pose, start the clock."""
        self.check(state)
        self.tare = np.concatenate([state.force, state.torque])[None]
        y0 = start_state(self.goal_pos[0], self.goal_rot[0], state.tcp_pos, state.tcp_rot)[None]
        self.skill = make_skill(self.params, self.goal_pos, self.goal_rot, y0, self.config.dmp.tau)
        self.filtered[:], self.coupled[:], self.aligned[:], self.spiral[:] = 0.0, 0.0, 0.0, 0.0
        self.tool_force = 0.0
        self.peak_force = 0.0
        self.t0 = self.last_t = state.t

    def elapsed(self, state: ArmState) -> float:
        return state.t - self.t0

    def check(self, state: ArmState) -> None:
        """Raise SafetyStop unless the reading is finite, slow enough and later than the last."""
        if not all(np.all(np.isfinite(v)) for v in state):
            raise SafetyStop("a measurement is NaN or infinite")
        speed = float(np.abs(state.qd).max())
        if speed >= self.config.max_joint_speed:
            raise SafetyStop(
                f"joint speed {speed:.2f} rad/s reached the limit {self.config.max_joint_speed:.2f}"
            )
        if state.t < self.last_t:
            raise SafetyStop(
                f"the arm's clock went back from {self.last_t:.3f} s to {state.t:.3f} s"
            )
        if self.tool_force > self.config.max_tool_force:
            raise SafetyStop(
                f"protective stop: sensed tool force {self.tool_force:.0f} N beyond the limit "
                f"{self.config.max_tool_force:.0f} N"
            )
        self.last_t = state.t

    def torque(self, state: ArmState) -> np.ndarray:
        """(6,) joint torques for this reading (N m, clamped to the UR5e's limits)."""
        self.check(state)
        return self._command(state)

    def _command(self, state: ArmState) -> np.ndarray:
        """`torque` for a reading that has passed `check`."""
        if self.skill is None:
            raise RuntimeError("SkillRuntime.torque before start")
        cfg, b = self.config, lambda a: a[None]  # one trial as a batch of one
        reading = external_wrench(b(state.force), b(state.torque), self.tare)
        # The filter and the damping are first-order lags with poles for one physics step
        # (TrialConfig.timestep); a command every n steps holds its reading n steps: pole^n.
        n = self.period_steps
        self.filtered = sensor.filter_step(self.filtered, reading, self.alpha**n)
        self.tool_force = float(np.linalg.norm(self.filtered[0, :3]))
        self.peak_force = max(self.peak_force, self.tool_force)
        wrench = wrench_to_goal(
            self.filtered, b(state.ft_rot), b(state.ft_pos - state.tcp_pos), self.goal_rot
        )
        a = cfg.coupling_pole**n
        self.coupled = a * self.coupled + (1.0 - a) * wrench
        wrench = self.coupled
        dt = cfg.timestep * self.period_steps  # the command's period
        self.aligned = aligned_rotation(self.control.search, self.aligned, wrench,
                                        b(state.tcp_pos), self.skill.goal_pos,
                                        self.skill.goal_rot, dt)  # fmt: skip
        self.spiral = spiral_state(self.control.search, self.spiral, wrench, b(state.tcp_pos),
                                   self.skill.goal_pos, self.skill.goal_rot, dt)  # fmt: skip
        meas = Measurement(
            t=np.array([self.elapsed(state)]),
            tcp_pos=b(state.tcp_pos),
            tcp_rot=b(state.tcp_rot),
            jac=b(state.jac),
            jdot_qdot=(b(state.jac_dot) @ state.qd[None, :, None])[..., 0],
            qvel=b(state.qd),
            mass=b(state.mass),
            bias=b(state.bias),
            wrench=wrench,
            aligned=self.aligned,
            spiral=self.spiral,
        )
        u = skill_torque(self.control, self.skill, self.basis, meas)[0]
        if not np.all(np.isfinite(u)):
            raise SafetyStop("the controller returned a non-finite torque")
        self.wrench = wrench[0]
        cfg = self.config
        if cfg.end_settled:  # the engines' settle test, on what the arm measures
            step = np.array([round(self.elapsed(state) / cfg.timestep)])
            self.settle = settle_update(self.settle, step, b(state.qd), b(state.tcp_pos), wrench,
                                        cfg, self.period_steps)  # fmt: skip
        return u

    @property
    def settled(self) -> bool:
        """The skill has settled (`TrialConfig.end_settled`): at rest or repeating the same
        motion, it cannot insert any more; `run_skill` stops it."""
        return bool(is_settled(self.settle, self.config)[0])

    def inserted(self, state: ArmState) -> bool:
        """The tcp (nominal tip) is inside the estimated hole's footprint near the table."""
        lateral = math.hypot(state.tcp_pos[0] - self.hole.x, state.tcp_pos[1] - self.hole.y)
        return bool(state.tcp_pos[2] < self.config.success_height and lateral < self.hole.size)


@dataclasses.dataclass(frozen=True)
class SkillRun:
    """How a run of the skill ended, and what each command period saw."""

    success: bool
    time_s: float  # at success, else when it stopped
    stopped: str  # "" unless a SafetyStop ended it, or "settled" (TrialConfig.end_settled)
    log: dict[str, np.ndarray]  # t (s), tcp_pos (m), wrench (goal frame), torque (N m)
    peak_force: float = 0.0  # N: the largest sensed tool force (TrialResult.peak_force)

    @property
    def protective_stop(self) -> bool:
        """The sensed tool force passed TrialConfig.max_tool_force (the UR5e's stop)."""
        return self.stopped.startswith("protective stop")

    @property
    def commands(self) -> int:
        return int(self.log["t"].shape[0])


def run_skill(
    arm: Arm,
    runtime: SkillRuntime,
    time_limit_s: float | None = None,
    done: Callable[[ArmState], bool] | None = None,
) -> SkillRun:
    """Drive `arm` with `runtime` until `done(state)` (default: `runtime.inserted`) or the time
    limit (default: the runtime's `TrialConfig.time_limit_s`). A SafetyStop holds the arm, and so
    does a skill that has settled (`SkillRuntime.settled`: stopped "settled", a failure)."""
    limit = runtime.config.time_limit_s if time_limit_s is None else time_limit_s
    if not (math.isfinite(limit) and limit > 0):
        raise UsageError(f"the time limit must be a positive number of seconds, got {limit!r}")
    done = done or runtime.inserted
    log = {"t": [], "tcp_pos": [], "wrench": [], "torque": []}
    stopped, success = "", False
    runtime.period_steps = max(1, round(arm.period / runtime.config.timestep))
    state = None
    try:
        state = arm.read()
        runtime.start(state)
        while True:
            elapsed = runtime.elapsed(state)
            runtime.check(state)
            if done(state):
                success = True
                break
            if elapsed >= limit - 1e-3 * arm.period:
                break
            if runtime.settled:
                arm.hold()
                stopped = "settled"
                break
            u = runtime._command(state)  # checked above
            arm.send(u)
            for key, value in zip(log, (elapsed, state.tcp_pos, runtime.wrench, u), strict=True):
                log[key].append(value)
            state = arm.read()
    except SafetyStop as stop:
        arm.hold()
        stopped = str(stop)
    arrays = {k: np.asarray(v, dtype=np.float64) for k, v in log.items()}
    elapsed = 0.0 if state is None else runtime.elapsed(state)  # None: the first read stopped
    return SkillRun(success, elapsed, stopped, arrays, runtime.peak_force)
