"""The learned skill as a control loop: hole estimate -> 38 numbers -> torques, every period.

    runtime = SkillRuntime(controller_vector("runs/paper", hole), hole)
    run = run_skill(arm, runtime, time_limit_s=60.0)

`SkillRuntime` runs the engines' control period (`engines/period.py`: `start`, `ends`,
`advance`) on a batch of one: the goal from the estimated hole (as in `task.goal_pose`), the
tare and the DMP's start taken at the first reading, then on each reading the period's end tests
and its command. The arm's reading enters the period's F/T pipeline as a sensor whose sampling,
noise, bias and latency are the arm's own (`sensor.filter_params`: the software filter alone);
a command every n physics steps is a period of n steps. It stops the skill (`SafetyStop`) on a
non-finite measurement or torque, a clock that runs backwards, and where the engines end a trial
as a failure: a joint too fast (`unstable`) or the protective stop; `run_skill` stops a skill
that has settled (`TrialConfig.end_settled`, stopped "settled"). On the simulated arm at 500 Hz a
run is the C engine's trial (tests/robot/test_runtime.py).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from mjx_peg.engines import period
from mjx_peg.engines.trial import (
    TrialConfig,
    as_controller_params,
    control_config,
    fitted_basis,
    is_success,
)
from mjx_peg.errors import UsageError
from mjx_peg.policy import observation
from mjx_peg.policy.export import Policy, load_policy
from mjx_peg.robot.arm import Arm, ArmState
from mjx_peg.skill import sensor
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.control_step import make_skill, start_state
from mjx_peg.skill.params import ControllerParams
from mjx_peg.skill.search import for_part
from mjx_peg.world import constants
from mjx_peg.world.task import goal_pose


class SafetyStop(RuntimeError):
    """The skill must stop now (one line says why)."""


@dataclasses.dataclass(frozen=True)
class HoleEstimate:
    """Where the skill believes the hole is and what part it takes: centre x, y (m), yaw (rad),
    shape, size S (m), the hole's clearance, hole size / peg size (None: the shape's paper
    fit, constants.HOLE_SCALE), and the yaw's declared uncertainty (+- rad; 0: none declared),
    which a skill with yaw_scale "uncertainty" sweeps (`search.for_part`)."""

    x: float
    y: float
    yaw: float
    shape: str
    size: float
    hole_scale: float | None = None
    yaw_uncertainty: float = 0.0

    def __post_init__(self):
        if self.shape not in constants.SHAPES:
            raise UsageError(f"hole shape must be one of {constants.SHAPES}, got {self.shape!r}")
        if self.hole_scale is None:
            object.__setattr__(self, "hole_scale", constants.HOLE_SCALE[self.shape])
        for name in ("x", "y", "yaw", "size", "hole_scale", "yaw_uncertainty"):
            if not math.isfinite(getattr(self, name)):
                raise UsageError(
                    f"hole {name} must be a finite number, got {getattr(self, name)!r}"
                )
        if self.size <= 0:
            raise UsageError(f"hole size must be positive (m), got {self.size!r}")
        if self.yaw_uncertainty < 0:
            raise UsageError(f"hole yaw uncertainty must be >= 0 rad, got {self.yaw_uncertainty!r}")
        lo, hi = constants.HOLE_SCALE_RANGE
        if not lo <= self.hole_scale <= hi:
            raise UsageError(
                f"hole scale (hole size / peg size) must lie in [{lo:g}, {hi:g}], "
                f"got {self.hole_scale!r}"
            )

    @classmethod
    def of_trial(cls, specs, index: int) -> HoleEstimate:
        """The estimate of trial `index` of a `TrialSpec` (its hole_est_pos/yaw, part, and the
        range its yaw error was drawn from as the declared uncertainty)."""
        x, y = (float(v) for v in specs.hole_est_pos[index])
        shape = constants.SHAPES[int(specs.shape_id[index])]
        return cls(x, y, float(specs.hole_est_yaw[index]), shape, float(specs.size[index]),
                   float(specs.hole_scale[index]), float(specs.angular_range[index]))  # fmt: skip

    def observation(self, layout: str = "names") -> np.ndarray:
        """(1, n) policy observation of this estimate in `layout` (observation.LAYOUTS)."""
        return observation.observe_part(
            layout,
            np.array([constants.SHAPES.index(self.shape)]),
            np.array([self.size]),
            np.array([self.hole_scale]),
            np.array([[self.x, self.y]]),
            np.array([self.yaw]),
        )


def controller_vector(policy: str | Policy, hole: HoleEstimate) -> np.ndarray:
    """(38,) controller numbers for `hole` from a loaded `Policy` (in its observation layout), a
    run directory holding policy.npz, or 'baseline'."""
    if isinstance(policy, str):
        if policy == "baseline":
            return baseline_params()
        policy = load_policy(policy)
    return policy.vectors_for(hole.observation(policy.layout))[0]


class SkillRuntime:
    """One insertion with fixed controller numbers: `start` at the first reading, then per
    reading `ends` (SafetyStop if the skill must stop) and `command`; `torque` is both."""

    def __init__(self, vector, hole: HoleEstimate, config: TrialConfig | None = None):
        self.config = cfg = config or TrialConfig()
        p = as_controller_params(vector, 1)
        # the search's learned constants, where the vector has them, stay (1,) arrays
        self.params = ControllerParams(p.k_t[0], p.k_theta[0], p.compliance[0], p.search)
        self.hole = hole
        self.basis = fitted_basis(cfg.movement)
        self.goal_pos, self.goal_rot = goal_pose(np.array([[hole.x, hole.y]]), np.array([hole.yaw]))
        # The estimated hole as the trial's hole (`trial.is_success`): its axis from the table
        # top (the board's bottom) up.
        self.hole_origin = np.array([[hole.x, hole.y, 0.0]])
        self.hole_axis = np.array([[0.0, 0.0, 1.0]])
        self.control = control_config(cfg)
        self.consts = self.trial = None  # the period's constants and state, from `start`
        self.t0 = self.last_t = 0.0
        self.wrench = np.zeros(6)  # the last wrench the compliance saw (goal frame)
        self.period_steps = 1  # physics steps (TrialConfig.timestep) per command; run_skill sets

    def start(self, state: ArmState) -> None:
        """Tare the F/T reading, take the DMP's start y0 from the tcp pose, start the clock."""
        self._check_reading(state)
        b = _one
        cfg = self.config
        tare = np.concatenate([state.force, state.torque])[None]
        y0 = start_state(self.goal_pos[0], self.goal_rot[0], state.tcp_pos, state.tcp_rot)[None]
        size = np.array([self.hole.size])
        search = for_part(cfg.search, self.params.search, cfg.movement.duration, size,
                          np.array([self.hole.yaw_uncertainty]))  # fmt: skip
        skill = make_skill(self.params, self.goal_pos, self.goal_rot, y0, cfg.dmp.tau, search)
        # The arm's reading is sampled, tared and delayed by its own path: the runtime adds
        # the software filter only, its pole for the command's period.
        ft = sensor.filter_params(cfg.sensor, cfg.timestep, np.zeros(1, np.uint32),
                                  self.period_steps)  # fmt: skip
        self.consts = period.make_consts(skill, ft, tare, self.hole_origin, self.hole_axis,
                                         size, b(state.tcp_pos))  # fmt: skip
        self.trial = period.start(cfg, self.consts)
        self.t0 = self.last_t = state.t
        self.ends(state)

    def elapsed(self, state: ArmState) -> float:
        return state.t - self.t0

    def _check_reading(self, state: ArmState) -> None:
        if not all(np.all(np.isfinite(v)) for v in state):
            raise SafetyStop("a measurement is NaN or infinite")
        if state.t < self.last_t:
            raise SafetyStop(
                f"the arm's clock went back from {self.last_t:.3f} s to {state.t:.3f} s"
            )

    def ends(self, state: ArmState) -> period.Ends:
        """The trial's end tests (`period.ends`) at this reading, the tcp in place of the tip
        (a robot measures no more) and the estimated hole in place of the true one, the period
        counted on the arm's clock. SafetyStop unless the reading is finite and later than the
        last, and the trial neither unstable (a joint as fast as `TrialConfig.max_joint_speed`,
        twice the UR5e's 180 deg/s, where the real arm would protective-stop) nor stopped (a
        sensed tool force beyond `TrialConfig.max_tool_force` at the last command, the UR5e's
        protective stop): the engines end such trials as failures."""
        if self.trial is None:
            raise RuntimeError("SkillRuntime.ends before start")
        self._check_reading(state)
        cfg, b, n = self.config, _one, self.period_steps
        step = round(self.elapsed(state) / (n * cfg.timestep))
        self.trial = self.trial._replace(step=np.array([step], dtype=np.int64))
        end = period.ends(cfg, self.consts, self.trial, b(state.tcp_pos), b(state.qd),
                          period_steps=n)  # fmt: skip
        if end.unstable[0]:
            speed = float(np.abs(state.qd).max())
            raise SafetyStop(
                f"joint speed {speed:.2f} rad/s reached the limit {cfg.max_joint_speed:.2f}"
            )
        if self.trial.stop[0]:
            raise SafetyStop(
                f"protective stop: sensed tool force {self.tool_force:.0f} N beyond the limit "
                f"{cfg.max_tool_force:.0f} N"
            )
        self.last_t = state.t
        return end

    def command(self, state: ArmState) -> np.ndarray:
        """(6,) joint torques (N m, clamped to the UR5e's limits) for a reading that has passed
        `ends`: `period.advance` on a batch of one. SafetyStop on a non-finite torque."""
        b = _one
        meas = period.PeriodMeasurement(
            qvel=b(state.qd),
            tcp_pos=b(state.tcp_pos),
            tcp_rot=b(state.tcp_rot),
            tip_pos=b(state.tcp_pos),
            ft=b(np.concatenate([state.force, state.torque])),
            ft_rot=b(state.ft_rot),
            ft_pos=b(state.ft_pos),
            jac=b(state.jac),
            jdot_qdot=(b(state.jac_dot) @ state.qd[None, :, None])[..., 0],
            mass=b(state.mass),
            bias=b(state.bias),
        )
        self.trial, u, wrench = period.advance(self.config, self.control, self.basis,
                                               self.consts, self.trial, meas, self.period_steps,
                                               zero_nonfinite=False)  # fmt: skip
        if not np.all(np.isfinite(u)):
            raise SafetyStop("the controller returned a non-finite torque")
        self.wrench = wrench[0]
        return u[0]

    def torque(self, state: ArmState) -> np.ndarray:
        """(6,) joint torques for this reading: `ends`, then `command`."""
        self.ends(state)
        return self.command(state)

    @property
    def tool_force(self) -> float:
        """N: the tool force the last command sensed (the F/T pipeline's output)."""
        if self.trial is None:
            return 0.0
        return float(np.linalg.norm(self.trial.sensor.filtered[0, :3]))

    @property
    def peak_force(self) -> float:
        """N: the largest sensed tool force so far (TrialResult.peak_force)."""
        return 0.0 if self.trial is None else float(self.trial.peak_force[0])

    def inserted(self, state: ArmState) -> bool:
        """The trial's success test (`trial.is_success`) on the tcp (the nominal tip) against
        the estimated hole: inside its footprint, near the table."""
        inside = is_success(_one(state.tcp_pos), self.hole_origin, self.hole_axis,
                            self.hole.size, self.config.success_height)  # fmt: skip
        return bool(inside[0])


def _one(a: np.ndarray) -> np.ndarray:
    """`a` as a batch of one trial."""
    return a[None]


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
    does a skill that has settled (the period's `Ends.settled`: stopped "settled", a failure)."""
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
            end = runtime.ends(state)
            if done(state):
                success = True
                break
            if elapsed >= limit - 1e-3 * arm.period:
                break
            if end.settled[0]:
                arm.hold()
                stopped = "settled"
                break
            u = runtime.command(state)
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
