"""The accelerator engine: the whole trial as one jitted, vmapped function over MJX state.

Each slot of the batch owns a copy of the few model fields that differ per trial (board pose,
grasp pose, friction), vmapped with the data. A physics step is split like C MuJoCo's
`mj_step1`/`mj_step2` (position and velocity stages, then the controller, then actuation,
constraint solve, sensors and the implicit-fast integrator), so the controller reads fresh
kinematics and a one-step-old wrench, as in the C engine. The loop is a `lax.while_loop` in
chunks of `recycle_every` steps; after each chunk, slots whose trial ended write their result and
load the next spec, so cost follows the simulated time actually used. Runs on MJX's JAX
implementation (the Warp implementation needs a CUDA device and `warp-lang`; see `impl`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx
from mujoco.mjx._src.support import jac_dot  # MJX's counterpart of mj_jacDot (not re-exported)

from mjx_peg.engines.trial import (
    TrialConfig,
    TrialResult,
    control_config,
    destination,
    fitted_basis,
    is_settled,
    is_success,
    sensor_params,
    settle_start,
    settle_update,
    trial_reward,
)
from mjx_peg.skill import sensor
from mjx_peg.skill.control_step import (
    Basis,
    Measurement,
    external_wrench,
    make_skill,
    skill_torque,
    start_state,
    wrench_to_goal,
)
from mjx_peg.skill.params import ControllerParams
from mjx_peg.world import constants, scene
from mjx_peg.world.rotations import quat_from_yaw
from mjx_peg.world.task import TrialSpec, goal_pose

# outcome array -> slot field it is written from
_OUTCOMES = {
    "success": "success",
    "unstable": "unstable",
    "steps": "step",
    "peak_force": "peak_force",
    "tip": "tip",
    "start_distance": "start_distance",
    "chatter": "chatter",
    "protective_stop": "stop",
    "settled": "settled",
}
_MODEL_FIELDS = ("board_pos3", "board_quat", "peg_pos", "peg_quat", "friction")


def step1(m: mjx.Model, d: mjx.Data) -> mjx.Data:
    """Position and velocity stages (C MuJoCo's mj_step1)."""
    d = mjx.fwd_position(m, d)
    d = mjx.sensor_pos(m, d)
    d = mjx.fwd_velocity(m, d)
    return mjx.sensor_vel(m, d)


def step2(m: mjx.Model, d: mjx.Data) -> mjx.Data:
    """Actuation, constraint solve, acceleration sensors, integration (mj_step2)."""
    d = mjx.fwd_actuation(m, d)
    d = mjx.fwd_acceleration(m, d)
    d = mjx.solve(m, d)
    d = mjx.sensor_acc(m, d)
    return mjx.implicit(m, d)


def _slot_inputs(specs: TrialSpec, params: ControllerParams, config: TrialConfig) -> dict:
    """Per-trial arrays the jitted function consumes (NumPy, leading dim = trials)."""
    n = len(specs)
    zeros = np.zeros(n)
    board_quat = np.asarray(quat_from_yaw(np.asarray(specs.board_yaw, dtype=np.float64)))
    dz, tilt_x, tilt_y = specs.grasp_error.T
    peg_pos = np.stack([zeros, zeros, dz], axis=-1)
    peg_quat = np.stack(
        [scene.grasp_quat(float(a), float(b)) for a, b in zip(tilt_x, tilt_y, strict=True)]
    )
    goal_pos, goal_rot = goal_pose(specs.hole_est_pos, specs.hole_est_yaw)
    sp = sensor_params(specs, config)
    return dict(
        **{f"sensor_{name}": value for name, value in sp._asdict().items()},
        board_pos3=np.concatenate([specs.board_pos, zeros[:, None]], axis=1),
        board_quat=board_quat,
        peg_pos=peg_pos,
        peg_quat=peg_quat,
        friction=np.asarray(specs.friction, dtype=np.float64),
        q0=np.asarray(specs.q0, dtype=np.float64),
        goal_pos=goal_pos,
        goal_rot=goal_rot,
        board_pos=np.asarray(specs.board_pos, dtype=np.float64),
        size=np.asarray(specs.size, dtype=np.float64),
        k_t=params.k_t,
        k_theta=params.k_theta,
        compliance=params.compliance,
    )


class _Program:
    """The compiled trial loop for one scene (shape, size)."""

    def __init__(self, model: mujoco.MjModel, config: TrialConfig, batch: int, recycle_every: int):
        self.ids = ids = scene.scene_ids(model)
        self.mx = mjx.put_model(model)
        self.config = config
        self.batch = batch
        self.recycle_every = recycle_every
        basis = fitted_basis(config.dmp)
        self.basis = Basis(*(jnp.asarray(a) for a in basis))
        self.control = control_config(config, jnp)
        self.qpos_adr = jnp.asarray(ids.qpos_adr)
        self.geoms = jnp.asarray(np.concatenate([ids.peg_geoms, ids.board_geoms]))
        self.run = jax.jit(self._run)

    # --- one slot -----------------------------------------------------------------------------
    def _slot_model(self, fields):
        """The shared model with this slot's board pose, grasp pose and friction."""
        ids, mx = self.ids, self.mx
        body_pos = jnp.asarray(mx.body_pos).at[ids.board_body].set(fields["board_pos3"])
        body_quat = jnp.asarray(mx.body_quat).at[ids.board_body].set(fields["board_quat"])
        friction = jnp.asarray(mx.geom_friction).at[self.geoms, 0].set(fields["friction"])
        return mx.replace(
            body_pos=body_pos.at[ids.peg_body].set(fields["peg_pos"]),
            body_quat=body_quat.at[ids.peg_body].set(fields["peg_quat"]),
            geom_friction=friction,
        )

    def _sense(self, m, d):
        ids = self.ids
        tcp_pos = d.site_xpos[ids.tcp_site]
        tcp_rot = d.site_xmat[ids.tcp_site].reshape(3, 3)
        jacp, jacr = mjx.jac(m, d, tcp_pos, ids.wrist3_body)
        jdp, jdr = jac_dot(m, d, tcp_pos, ids.wrist3_body)
        jac = jnp.concatenate([jacp.T, jacr.T], axis=0)
        jdot_qdot = jnp.concatenate([jdp.T, jdr.T], axis=0) @ d.qvel
        force = d.sensordata[ids.ft_force_adr : ids.ft_force_adr + 3]
        torque = d.sensordata[ids.ft_torque_adr : ids.ft_torque_adr + 3]
        rot_ft = d.site_xmat[ids.ft_site].reshape(3, 3)
        lever = d.site_xpos[ids.ft_site] - tcp_pos
        return tcp_pos, tcp_rot, jac, jdot_qdot, force, torque, rot_ft, lever

    def _init(self, inp):
        """Data at rest at q0 under gravity compensation, the tare, and the skill constants."""
        cfg = self.config
        fields = {k: inp[k] for k in _MODEL_FIELDS}
        m = self._slot_model(fields)
        d = mjx.make_data(m)
        d = d.replace(qpos=d.qpos.at[self.qpos_adr].set(inp["q0"]))
        d = mjx.forward(m, d)
        d = d.replace(ctrl=scene.bias_torque(d.qfrc_bias, d.qfrc_passive, self.ids.dof_adr))
        d = mjx.forward(m, d)
        tcp_pos, tcp_rot, _, _, force, torque, _, _ = self._sense(m, d)
        tare = jnp.concatenate([force, torque])
        y0 = start_state(inp["goal_pos"], inp["goal_rot"], tcp_pos, tcp_rot)
        params = ControllerParams(inp["k_t"], inp["k_theta"], inp["compliance"])
        skill = make_skill(params, inp["goal_pos"], inp["goal_rot"], y0, cfg.dmp.tau)
        sp = sensor.SensorParams(*(inp[f"sensor_{name}"] for name in sensor.SensorParams._fields))
        tip = d.site_xpos[self.ids.tip_site]
        start_distance = jnp.linalg.norm(tip - destination(inp["board_pos"]))
        slot = dict(
            fields=fields,
            skill=skill,
            tare=tare,
            board_pos=inp["board_pos"],
            size=inp["size"],
            start_distance=start_distance,
            step=jnp.zeros((), jnp.int32),
            peak_force=jnp.zeros(()),
            ended=jnp.zeros((), bool),
            success=jnp.zeros((), bool),
            unstable=jnp.zeros((), bool),
            settled=jnp.zeros((), bool),
            settle=settle_start((), jnp),
            tip=tip,
            sensor=sp,
            sensor_state=sensor.initial_state(sp, cfg.sensor.max_delay_steps + 1, tare.dtype),
            coupled=jnp.zeros(6, tare.dtype),
            chatter_ring=jnp.zeros(cfg.chatter_steps, tare.dtype),
            axial=jnp.zeros((), tare.dtype),
            chatter=jnp.zeros((), tare.dtype),
            stop=jnp.zeros((), bool),
        )
        return d, slot

    def _step(self, d, slot):
        """One control period of one slot; ended slots keep their outcome frozen."""
        cfg = self.config
        m = self._slot_model(slot["fields"])
        d = step1(m, d)
        tcp_pos, tcp_rot, jac, jdq, force, torque, rot_ft, lever = self._sense(m, d)
        skill = slot["skill"]
        tip = d.site_xpos[self.ids.tip_site]
        step = slot["step"]
        stop = slot["stop"]  # set by the previous period's sensed force
        success = is_success(tip, slot["board_pos"], slot["size"], cfg.success_height) & ~stop
        finite = jnp.all(jnp.isfinite(tip)) & jnp.all(jnp.isfinite(d.qvel))
        unstable = ~finite | jnp.any(jnp.abs(d.qvel) > cfg.max_joint_speed)
        settled = is_settled(slot["settle"], cfg) & ~success & ~unstable & ~stop
        ended_now = ~slot["ended"] & (success | unstable | stop | settled | (step >= cfg.max_steps))
        live = ~(slot["ended"] | ended_now)
        # The F/T pipeline, the compliance damping and the contact metrics (as the C engine).
        true = external_wrench(force, torque, slot["tare"])
        sensed, sensor_state = sensor.step(slot["sensor"], slot["sensor_state"], true, step)
        force_mag = jnp.linalg.norm(sensed[:3])
        ring = slot["chatter_ring"]
        count = jnp.clip(step - 1, 0, ring.shape[0])
        chatter = jnp.where(count > 0, jnp.sum(ring) / jnp.maximum(count, 1), 0.0)
        axial = skill.goal_rot[:, 2] @ (rot_ft @ true[:3])
        ring = jnp.where(
            live & (step >= 1),
            ring.at[step % ring.shape[0]].set(jnp.abs(axial - slot["axial"])),
            ring,
        )
        wrench = wrench_to_goal(sensed, rot_ft, lever, skill.goal_rot)
        a = cfg.coupling_pole
        coupled = a * slot["coupled"] + (1.0 - a) * wrench
        meas = Measurement(
            t=step * cfg.timestep,
            tcp_pos=tcp_pos,
            tcp_rot=tcp_rot,
            jac=jac,
            jdot_qdot=jdq,
            qvel=d.qvel,
            mass=mjx.full_m(m, d),
            bias=scene.bias_torque(d.qfrc_bias, d.qfrc_passive, self.ids.dof_adr),
            wrench=coupled,
        )
        u = skill_torque(self.control, skill, self.basis, meas)
        u = jnp.where(jnp.isfinite(u) & live, u, 0.0)
        d_qvel = d.qvel  # this period's, for the settle test
        d = step2(m, d.replace(ctrl=u))

        def keep(new, old):  # carried state advances only while the trial runs
            return jax.tree.map(lambda a, b: jnp.where(live, a, b), new, old)

        slot = dict(
            slot,
            step=jnp.where(live, step + 1, step),
            peak_force=jnp.maximum(slot["peak_force"], jnp.where(live, force_mag, 0.0)),
            ended=slot["ended"] | ended_now,
            success=jnp.where(ended_now, success & ~unstable, slot["success"]),
            unstable=jnp.where(ended_now, unstable, slot["unstable"]),
            settled=jnp.where(ended_now, settled, slot["settled"]),
            tip=jnp.where(live | ended_now, tip, slot["tip"]),
            sensor_state=keep(sensor_state, slot["sensor_state"]),
            coupled=keep(coupled, slot["coupled"]),
            chatter_ring=ring,
            axial=keep(axial, slot["axial"]),
            chatter=jnp.where(ended_now, chatter, slot["chatter"]),
            stop=slot["stop"] | (live & (force_mag > cfg.max_tool_force)),
        )
        if cfg.end_settled:
            slot["settle"] = settle_update(slot["settle"], step, d_qvel, tcp_pos, coupled, cfg)
        return d, slot

    # --- the batch ----------------------------------------------------------------------------
    def _run(self, inputs: dict):
        """Outcomes of all n trials of `inputs` (leading dim n), b slots recycled until done."""
        n = inputs["q0"].shape[0]
        b = self.batch
        init = jax.vmap(self._init)
        step = jax.vmap(self._step)

        def take(indices):
            safe = jnp.minimum(indices, n - 1)
            return jax.tree.map(lambda a: a[safe], inputs)

        # Every slot starts ended and empty; the first chunk loads it. `init` is traced once.
        shapes = jax.eval_shape(init, take(jnp.arange(b)))
        d, slot = jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), shapes)
        slot = dict(slot, ended=jnp.ones(b, bool))
        index = jnp.full(b, n)  # index n: no spec (writes to it are dropped)
        out = dict(
            success=jnp.zeros(n, bool),
            unstable=jnp.zeros(n, bool),
            settled=jnp.zeros(n, bool),
            steps=jnp.zeros(n, jnp.int32),
            peak_force=jnp.zeros(n),
            tip=jnp.zeros((n, 3)),
            start_distance=jnp.ones(n),
            chatter=jnp.zeros(n),
            protective_stop=jnp.zeros(n, bool),
        )
        state = (d, slot, index, jnp.asarray(0), out)

        def chunk(state):
            d, slot, index, next_index, out = state
            # Slots whose trial ended write their outcome and take the next spec.
            dest = jnp.where(slot["ended"], index, n)
            out = {
                key: out[key].at[dest].set(slot[name], mode="drop")
                for key, name in _OUTCOMES.items()
            }
            finished = slot["ended"]
            new_index = jnp.where(finished, next_index + jnp.cumsum(finished) - 1, index)
            new_index = jnp.minimum(new_index, n)
            next_index = jnp.minimum(next_index + jnp.sum(finished), n)

            def reload(args):
                d2, slot2 = init(take(new_index))
                slot2 = dict(slot2, ended=new_index >= n)  # no spec left: stays ended

                def pick(new, old):
                    mask = finished.reshape(finished.shape + (1,) * (new.ndim - 1))
                    return jnp.where(mask, new, old)

                return jax.tree.map(pick, (d2, slot2), args)

            d, slot = jax.lax.cond(jnp.any(finished), reload, lambda a: a, (d, slot))
            d, slot = jax.lax.fori_loop(0, self.recycle_every, lambda _, c: step(*c), (d, slot))
            return d, slot, new_index, next_index, out

        def pending(state):
            _, _, index, next_index, _ = state
            return jnp.any(index < n) | (next_index < n)

        *_, out = jax.lax.while_loop(pending, chunk, state)
        return out


@functools.lru_cache(maxsize=16)
def _program(shape: str, size: float, config: TrialConfig, batch: int, recycle_every: int):
    return _Program(scene.load_model(shape, size), config, batch, recycle_every)


def run_trials(
    specs: TrialSpec,
    params: ControllerParams,
    config: TrialConfig,
    batch: int | None = None,
    recycle_every: int = 50,
    progress: Callable[[int], None] | None = None,
) -> TrialResult:
    """Run every trial of `specs` with per-trial `params` on MJX, grouped by scene."""
    n = len(specs)
    inputs_all = _slot_inputs(specs, params, config)
    keys = [
        (constants.SHAPES[int(s)], round(float(z), 9))
        for s, z in zip(specs.shape_id, specs.size, strict=True)
    ]
    out_arrays = {
        "success": np.zeros(n, bool),
        "unstable": np.zeros(n, bool),
        "settled": np.zeros(n, bool),
        "steps": np.zeros(n, np.int64),
        "peak_force": np.zeros(n),
        "final_tip_pos": np.zeros((n, 3)),
        "start_distance": np.ones(n),
        "chatter": np.zeros(n),
        "protective_stop": np.zeros(n, bool),
    }
    for key in sorted(set(keys)):
        rows = np.array([i for i, k in enumerate(keys) if k == key])
        b = min(batch or 256, len(rows))
        program = _program(key[0], key[1], config, b, recycle_every)
        inputs = {k: jnp.asarray(v[rows]) for k, v in inputs_all.items()}
        out = jax.device_get(program.run(inputs))
        out_arrays["success"][rows] = out["success"]
        out_arrays["unstable"][rows] = out["unstable"]
        out_arrays["settled"][rows] = out["settled"]
        out_arrays["steps"][rows] = out["steps"]
        out_arrays["peak_force"][rows] = out["peak_force"]
        out_arrays["final_tip_pos"][rows] = out["tip"]
        out_arrays["start_distance"][rows] = out["start_distance"]
        out_arrays["chatter"][rows] = out["chatter"]
        out_arrays["protective_stop"][rows] = out["protective_stop"]
        if progress is not None:
            progress(len(rows))
    success = out_arrays["success"]
    reward = trial_reward(
        success,
        out_arrays["final_tip_pos"],
        np.asarray(specs.board_pos, dtype=np.float64),
        out_arrays["start_distance"],
        config.reward,
    )
    return TrialResult(
        success=success,
        time_s=out_arrays["steps"] * config.timestep,
        final_tip_pos=out_arrays["final_tip_pos"],
        peak_force=out_arrays["peak_force"],
        reward=np.asarray(reward),
        unstable=out_arrays["unstable"],
        steps=out_arrays["steps"],
        settled=out_arrays["settled"],
        chatter=out_arrays["chatter"],
        protective_stop=out_arrays["protective_stop"],
    )
