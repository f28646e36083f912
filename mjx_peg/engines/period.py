"""One control period of a trial: every rule a period decides, written once for the engines and
the robot runtime.

Per period, at the arm's measurement (the physics' position and velocity stages, the F/T
reading one physics step old):

1. `ends`: the end tests at this measurement: success (tip through the hole, near the table),
   unstable (joints beyond `max_joint_speed`, NaN, or the engine's own physics check), the
   protective stop (set by an earlier period's sensed force), settled (`trial.settle_update`),
   out of time; success needs neither of the failures.
2. `advance`, for a trial that goes on: the F/T pipeline (`skill.sensor`) on the tared reading;
   the contact metrics (peak sensed force, the 150 N protective stop, the chatter ring of the
   true axial force); the compliance damping W_k = a_c W_(k-1) + (1 - a_c) F_k (Eq. 4 with
   D_c = T_c K_c, `skill.control_step`); the search's goal rotation (`search.aligned_rotation`)
   and spiral (`search.spiral_state`); the settle test; the control step's joint torques.
3. `result`: what an ended trial records (`TrialResult`'s fields).

`period` is 1 then 2. A period lasts m = `period_steps` physics steps of
`TrialConfig.timestep` (the engines command every step, m = 1; an arm commanded at 125 Hz,
m = 4), the torque held over them: the damping's pole is then a_c^m, the search's states advance
by m T, the clock and the settle test count m steps a period (the F/T filter's pole is its
`SensorParams`', `sensor.filter_params` for an arm's own sensor path).
Written over the array-API namespace of the inputs like `skill/`: the C engine runs it batched
in NumPy over its live rows, the MJX engine inside its jitted, vmapped step, the robot runtime
on a batch of one. What stays in the engines is the physics: stepping, and gathering a
`PeriodMeasurement`. It imports neither JAX nor MuJoCo.
"""

from __future__ import annotations

from typing import NamedTuple

from mjx_peg.array_api import namespace_of, ring_write, tree_map
from mjx_peg.engines.trial import (
    SettleState,
    TrialConfig,
    chatter_of,
    is_settled,
    is_success,
    settle_start,
    settle_update,
    trial_reward,
)
from mjx_peg.skill import sensor
from mjx_peg.skill.control_step import (
    Basis,
    ControlConfig,
    Measurement,
    SkillConsts,
    external_wrench,
    skill_torque,
    wrench_to_goal,
)
from mjx_peg.skill.search import aligned_rotation, spiral_state


class TrialConsts(NamedTuple):
    """Per trial, fixed at its start (a pytree; leading dims are trials)."""

    skill: SkillConsts  # the control step's constants
    sensor: sensor.SensorParams  # the F/T pipeline's draws
    tare: object  # (..., 6) the F/T reading at rest at the start (force, torque; sensor frame)
    hole_origin: object  # (..., 3) the true hole's axis at the board's bottom (`task.hole_frame`)
    hole_axis: object  # (..., 3) the true hole's unit axis
    size: object  # (...,) hole size (m)
    start_distance: object  # (...,) tip to hole_origin at the start (m)


class TrialState(NamedTuple):
    """What a trial carries from one control period to the next (a pytree)."""

    step: object  # (...,) int: control periods since the start (the chatter ring counts them)
    peak_force: object  # (...,) N: largest sensed force so far
    stop: object  # (...,) bool: the sensed force has passed max_tool_force
    sensor: sensor.SensorState
    coupled: object  # (..., 6) the compliance damping's output W, goal frame
    chatter_ring: object  # (..., W) |F_k - F_(k-1)| of the true axial force at k mod W, k >= 1
    axial: object  # (...,) N: the last period's true axial force
    settle: SettleState
    aligned: object  # (..., 3) rad: the goal's rotation found by the search's alignment
    spiral: object  # (..., 3) the search's spiral: resting time, resting height, phase


class PeriodMeasurement(NamedTuple):
    """What an engine gathers of a trial each period (a pytree; leading dims are trials)."""

    qvel: object  # (..., n) joint velocities
    tcp_pos: object  # (..., 3) world
    tcp_rot: object  # (..., 3, 3)
    tip_pos: object  # (..., 3) peg tip (true; for the end tests and the result only)
    ft: object  # (..., 6) F/T site reading: force, torque (site frame, untared)
    ft_rot: object  # (..., 3, 3) F/T site orientation
    ft_pos: object  # (..., 3) F/T site position
    jac: object  # (..., 6, n) tcp Jacobian [linear; angular], world
    jdot_qdot: object  # (..., 6) Jd qd of the tcp
    mass: object  # (..., n, n) joint-space inertia H
    bias: object  # (..., n) h: bias torques less passive forces


class Ends(NamedTuple):
    """The end tests of one period (`ends`), (...,) bool each."""

    success: object  # inserted, and neither unstable nor stopped
    unstable: object
    settled: object
    ended: object  # any of these, the protective stop, or out of time


class Outcome(NamedTuple):
    """What an ended trial records (`result`); the fields of `TrialResult` but time_s."""

    success: object
    final_tip_pos: object
    peak_force: object
    reward: object
    unstable: object
    steps: object
    settled: object
    chatter: object
    protective_stop: object


def make_consts(skill: SkillConsts, sensor_params, tare, hole_origin, hole_axis, size,
                tip_pos) -> TrialConsts:  # fmt: skip
    """The constants of trials starting with the tip at `tip_pos` (..., 3)."""
    xp = namespace_of(tip_pos, hole_origin)
    distance = xp.linalg.vector_norm(tip_pos - hole_origin, axis=-1)
    return TrialConsts(skill, sensor_params, tare, hole_origin, hole_axis, size, distance)


def start(config: TrialConfig, consts: TrialConsts) -> TrialState:
    """The state of trials at their start (period 0, at the tare)."""
    xp = namespace_of(consts.tare)
    batch, dtype = tuple(consts.tare.shape[:-1]), consts.tare.dtype
    return TrialState(
        # JAX's default integers are 32-bit; NumPy counts in int64, as MjData's steps do
        step=xp.zeros(batch, dtype=xp.int64 if xp.__name__ == "numpy" else xp.int32),
        peak_force=xp.zeros(batch, dtype=dtype),
        stop=xp.zeros(batch, dtype=bool),
        sensor=sensor.initial_state(consts.sensor, config.sensor.max_delay_steps + 1, dtype),
        coupled=xp.zeros((*batch, 6), dtype=dtype),
        chatter_ring=xp.zeros((*batch, config.chatter_steps), dtype=dtype),
        axial=xp.zeros(batch, dtype=dtype),
        settle=settle_start(batch, xp),
        aligned=xp.zeros((*batch, 3), dtype=dtype),
        spiral=xp.zeros((*batch, 3), dtype=dtype),
    )


def physics_steps(step, period_steps: int = 1):
    """(...,) int: the physics steps since the start after `step` (...,) control periods of
    `period_steps` physics steps each."""
    return step if period_steps == 1 else step * period_steps


def ends(config: TrialConfig, consts: TrialConsts, state: TrialState, tip_pos, qvel,
         physics_ok=None, period_steps: int = 1) -> Ends:  # fmt: skip
    """The end tests at this period's measurement (tip_pos (..., 3), qvel (..., n));
    physics_ok (...,) bool: the engine's own check of its step, if it has one (the C engine:
    MuJoCo did not reset the data); period_steps: physics steps per control period."""
    xp = namespace_of(tip_pos, qvel)
    inside = is_success(tip_pos, consts.hole_origin, consts.hole_axis, consts.size,
                        config.success_height)  # fmt: skip
    # Too fast, NaN or infinite joint speeds fail the speed test alike.
    fast = ~(xp.max(xp.abs(qvel), axis=-1) < config.max_joint_speed)
    unstable = fast | ~xp.all(xp.isfinite(tip_pos), axis=-1)
    if physics_ok is not None:
        unstable = unstable | ~physics_ok
    stop = state.stop
    success = inside & ~stop & ~unstable
    settled = is_settled(state.settle, config) & ~inside & ~unstable & ~stop
    out_of_time = physics_steps(state.step, period_steps) >= config.max_steps
    ended = success | unstable | stop | settled | out_of_time
    return Ends(success, unstable, settled, ended)


def chatter(state: TrialState):
    """(...,) N: the chatter metric of trials in `state` (`trial.chatter_of`)."""
    return chatter_of(state.chatter_ring, state.step)


def result(config: TrialConfig, consts: TrialConsts, state: TrialState, tip_pos,
           end: Ends) -> Outcome:  # fmt: skip
    """What trials ending at this period record."""
    reward = trial_reward(end.success, tip_pos, consts.hole_origin, consts.start_distance,
                          config.reward)  # fmt: skip
    return Outcome(end.success, tip_pos, state.peak_force, reward, end.unstable, state.step,
                   end.settled, chatter(state), state.stop)  # fmt: skip


def advance(config: TrialConfig, control: ControlConfig, basis: Basis, consts: TrialConsts,
            state: TrialState, meas: PeriodMeasurement, period_steps: int = 1,
            zero_nonfinite: bool = True):  # fmt: skip
    """(state, torques (..., n), wrench (..., 6)): one period of trials that go on, a period of
    `period_steps` physics steps (module docstring).

    wrench: what the compliance sees (goal frame, at the tcp), after the F/T pipeline and the
    damping. zero_nonfinite: a non-finite torque becomes 0 (the engines, whose end tests then
    see the physics); False: returned as it is (the robot runtime stops the arm on it). On NumPy
    the chatter ring is written in place (`array_api.ring_write`).
    """
    xp = namespace_of(meas.ft, meas.qvel)
    step, goal_rot = state.step, consts.skill.goal_rot
    true = external_wrench(meas.ft[..., :3], meas.ft[..., 3:], consts.tare)  # sensor frame
    sensed, sensor_state = sensor.step(consts.sensor, state.sensor, true, step)
    force = xp.linalg.vector_norm(sensed[..., :3], axis=-1)
    peak = xp.maximum(state.peak_force, force)
    stop = state.stop | (force > config.max_tool_force)
    # Chatter: |F_k - F_(k-1)| of the true axial force (the world force along goal z).
    f_world = xp.sum(meas.ft_rot * true[..., None, :3], axis=-1)
    axial = xp.sum(goal_rot[..., :, 2] * f_world, axis=-1)
    ring = ring_write(state.chatter_ring, step, xp.abs(axial - state.axial), step >= 1)
    lever = meas.ft_pos - meas.tcp_pos
    wrench = wrench_to_goal(sensed, meas.ft_rot, lever, goal_rot)
    a = config.coupling_pole**period_steps  # a first-order lag held over n steps
    coupled = a * state.coupled + (1.0 - a) * wrench
    skill, dt = consts.skill, config.timestep * period_steps
    aligned = aligned_rotation(control.search, state.aligned, coupled, meas.tcp_pos,
                               skill.goal_pos, skill.goal_rot, dt, skill.search)  # fmt: skip
    spiral = spiral_state(control.search, state.spiral, coupled, meas.tcp_pos, skill.goal_pos,
                          skill.goal_rot, dt)  # fmt: skip
    settle, steps = state.settle, physics_steps(step, period_steps)
    if config.end_settled:
        settle = settle_update(settle, steps, meas.qvel, meas.tcp_pos, coupled, config,
                               period_steps)  # fmt: skip
    torques = skill_torque(
        control,
        consts.skill,
        basis,
        Measurement(
            t=steps * config.timestep,
            tcp_pos=meas.tcp_pos,
            tcp_rot=meas.tcp_rot,
            jac=meas.jac,
            jdot_qdot=meas.jdot_qdot,
            qvel=meas.qvel,
            mass=meas.mass,
            bias=meas.bias,
            wrench=coupled,
            aligned=aligned,
            spiral=spiral,
        ),
    )
    if zero_nonfinite:
        torques = xp.where(xp.isfinite(torques), torques, 0.0)
    new = TrialState(step + 1, peak, stop, sensor_state, coupled, ring, axial, settle, aligned,
                     spiral)  # fmt: skip
    return new, torques, coupled


def period(config: TrialConfig, control: ControlConfig, basis: Basis, consts: TrialConsts,
           state: TrialState, meas: PeriodMeasurement):  # fmt: skip
    """(ends, state, torques, wrench): `ends` then `advance` at one measurement. The state and
    torques of a trial that ended are those it would have had: the caller keeps or drops them."""
    end = ends(config, consts, state, meas.tip_pos, meas.qvel)
    return (end, *advance(config, control, basis, consts, state, meas))


__all__ = [
    "Ends",
    "Outcome",
    "PeriodMeasurement",
    "TrialConsts",
    "TrialState",
    "advance",
    "chatter",
    "ends",
    "make_consts",
    "period",
    "physics_steps",
    "result",
    "start",
    "tree_map",
]
