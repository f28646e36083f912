"""A simulated UR5e behind the `Arm` interface: one trial of a `TrialSpec` in C MuJoCo.

The physics steps at the scene's 2 ms. `command_steps` physics steps pass between two commands
and the torque is held in between (zero-order hold), as a robot that takes effort commands at a
lower rate than it senses: 1 is the 500 Hz of training and evaluation, 4 the 125 Hz at which the
paper's UR5e took effort commands. Each `read` runs `mj_step1` (fresh kinematics, mass matrix and
bias; the F/T sensor still holds the previous step's reading, as on a real robot) and `send` runs
`mj_step2`, then `mj_step` for the rest of the command period: at `command_steps=1` this is the
C engine's step, so a run of the runtime on this arm ends as the engine's trial.

`actuator_lag_s` > 0 puts a first-order lag between the command and the joint torque, as a real
arm's current loop and drive do (a UR5e's: a few ms): at every physics
step of dt the applied torque moves towards the held command by 1 - exp(-dt / T_a), the exact
response of T_a du/dt = u_cmd - u to the held command, sampled at each step's start. 0 (the
default): the command is the torque, as in training.

The F/T reading goes through the sensor's hardware stage (`sensor.hardware_step`: sampling, the
trial's noise and bias, latency) as the engines do, once per read (at `command_steps=1`, once per
control period, the engines' readings); the robot runtime applies the software filter.
"""

from __future__ import annotations

import mujoco
import numpy as np

from mjx_peg.engines.trial import TrialConfig, chatter_of, is_success, sensor_params
from mjx_peg.errors import UsageError
from mjx_peg.robot.arm import ArmState
from mjx_peg.skill import sensor
from mjx_peg.world import constants, scene
from mjx_peg.world.task import TrialSpec, hole_frame


class SimArm:
    """Trial `index` of `specs` set up and held still, ready for the skill."""

    def __init__(
        self,
        specs: TrialSpec,
        index: int = 0,
        command_steps: int = 1,
        success_height: float = 0.02,
        config: TrialConfig | None = None,
        actuator_lag_s: float = 0.0,
    ):
        if type(command_steps) is not int or command_steps < 1:
            raise UsageError(f"command_steps must be a positive integer, got {command_steps!r}")
        if not (np.isfinite(actuator_lag_s) and actuator_lag_s >= 0):
            raise UsageError(f"actuator_lag_s must be a number >= 0, got {actuator_lag_s!r}")
        if not 0 <= index < len(specs):
            raise UsageError(f"trial index {index} is outside the {len(specs)} trials")
        s = specs.take([index])
        self.size = float(s.size[0])
        (self.hole_origin,), (self.hole_axis,) = hole_frame(s)
        shape = constants.SHAPES[int(s.shape_id[0])]
        self.model = m = scene.load_model(shape, self.size, float(s.hole_scale[0]))
        self.data = d = mujoco.MjData(m)
        self.ids = ids = scene.scene_ids(m)
        scene.start_trial(s, 0, m, d, ids)
        self.hold_torque = d.ctrl[ids.actuator_ids].copy()
        # the lag's state: the torque the joints get, from the set-up's holding torque
        dt = float(m.opt.timestep)
        self.lag_keep = float(np.exp(-dt / actuator_lag_s)) if actuator_lag_s > 0 else 0.0
        self.applied = self.hold_torque.copy()
        self.command_steps = command_steps
        self.period = command_steps * float(m.opt.timestep)
        self.success_height = success_height
        self.steps = 0  # physics steps since the set-up
        nv = m.nv
        self._jl, self._ja = np.zeros((3, nv)), np.zeros((3, nv))
        self._jdl, self._jda = np.zeros((3, nv)), np.zeros((3, nv))
        self._mass = np.zeros((nv, nv))
        # The F/T sensor: the trial's pipeline constants, the reading at rest (the tare the
        # runtime will take), the delay line.
        config = config or TrialConfig()
        self._sensor = sensor_params(s, config)
        sd, fa, ta = d.sensordata, ids.ft_force_adr, ids.ft_torque_adr  # after start_trial
        self._rest = np.concatenate([sd[fa : fa + 3], sd[ta : ta + 3]])[None]
        self._history = np.zeros((1, config.sensor.max_delay_steps + 1, 6))
        # The engines' chatter metric of the true axial force (world z: the goal's z axis is
        # vertical), one entry per reading, which only the simulation knows.
        self._ring, self._axial, self._reads = np.zeros((1, config.chatter_steps)), 0.0, 0

    def read(self) -> ArmState:
        m, d, ids = self.model, self.data, self.ids
        mujoco.mj_step1(m, d)
        tcp = ids.tcp_site
        mujoco.mj_jacSite(m, d, self._jl, self._ja, tcp)
        mujoco.mj_jacDot(m, d, self._jdl, self._jda, d.site_xpos[tcp], ids.wrist3_body)
        mujoco.mj_fullM(m, d, self._mass)
        dof = ids.dof_adr
        sd, fa, ta = d.sensordata, ids.ft_force_adr, ids.ft_torque_adr
        raw = np.concatenate([sd[fa : fa + 3], sd[ta : ta + 3]])[None]
        rot_ft = d.site_xmat[ids.ft_site].reshape(3, 3)
        axial = float(rot_ft[2] @ (self._rest - raw)[0, :3])
        if self._reads >= 1:
            self._ring[0, self._reads % self._ring.shape[1]] = abs(axial - self._axial)
        self._axial, self._reads = axial, self._reads + 1
        reading, self._history = sensor.hardware_step(
            self._sensor, self._history, self._rest - raw, np.array([self.steps])
        )
        raw = (self._rest - reading)[0]  # back to the sensor's convention (load on the peg)
        return ArmState(
            t=self.steps * float(m.opt.timestep),  # the step count: d.time accumulates rounding
            q=d.qpos[ids.qpos_adr].copy(),
            qd=d.qvel[dof].copy(),
            tcp_pos=d.site_xpos[tcp].copy(),
            tcp_rot=d.site_xmat[tcp].reshape(3, 3).copy(),
            jac=np.concatenate([self._jl, self._ja])[:, dof],
            jac_dot=np.concatenate([self._jdl, self._jda])[:, dof],
            mass=self._mass[np.ix_(dof, dof)].copy(),
            bias=scene.bias_torque(d.qfrc_bias, d.qfrc_passive, dof),
            force=raw[:3],
            torque=raw[3:],
            ft_pos=d.site_xpos[ids.ft_site].copy(),
            ft_rot=d.site_xmat[ids.ft_site].reshape(3, 3).copy(),
        )

    def send(self, torque: np.ndarray) -> None:
        m, d, actuators = self.model, self.data, self.ids.actuator_ids
        command = np.where(np.isfinite(torque), torque, 0.0)
        if self.lag_keep == 0.0:  # no lag: the command is held over its period
            d.ctrl[actuators] = command
            mujoco.mj_step2(m, d)
            if self.command_steps > 1:
                mujoco.mj_step(m, d, nstep=self.command_steps - 1)
        else:
            for k in range(self.command_steps):
                self.applied = self.lag_keep * self.applied + (1.0 - self.lag_keep) * command
                d.ctrl[actuators] = self.applied
                if k == 0:
                    mujoco.mj_step2(m, d)
                else:
                    mujoco.mj_step(m, d)
        self.steps += self.command_steps

    def hold(self) -> None:
        """Hold the start's gravity-compensation torques (the sim's protective stop)."""
        self.data.ctrl[self.ids.actuator_ids] = self.hold_torque

    @property
    def rest_reading(self) -> np.ndarray:
        """(6,) the F/T reading at rest at the set-up (force, torque; sensor frame, the load on
        the peg), before the sensor's noise and bias: the zero a real sensor is tared to."""
        return self._rest[0].copy()

    def chatter(self) -> float:
        """N: the engines' chatter (TrialResult.chatter) of the true axial contact force, over
        the readings so far (one per command period)."""
        return float(chatter_of(self._ring, self._reads)[0])

    def tip_pos(self) -> np.ndarray:
        """(3,) the true peg tip (site `peg_tip`), which a real robot cannot measure."""
        return self.data.site_xpos[self.ids.tip_site].copy()

    def inserted(self, state: ArmState | None = None) -> bool:
        """The trial's success test on the true tip (as the engines judge it)."""
        return bool(is_success(self.tip_pos(), self.hole_origin, self.hole_axis, self.size,
                               self.success_height))  # fmt: skip
