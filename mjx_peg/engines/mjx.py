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

from mjx_peg.engines import period
from mjx_peg.engines.trial import (
    TrialConfig,
    TrialResult,
    control_config,
    fitted_basis,
    sensor_params,
)
from mjx_peg.skill import sensor
from mjx_peg.skill.control_step import Basis, make_skill, start_state
from mjx_peg.skill.params import ControllerParams
from mjx_peg.skill.search import LEARNED, SearchValues, for_part
from mjx_peg.world import constants, scene
from mjx_peg.world.task import TrialSpec, board_pose, goal_pose, hole_frame

_MODEL_FIELDS = ("board_pos3", "board_quat", "peg_pos", "peg_quat", "friction")

# XLA's CPU fusion emitters (jax 0.9.2) turn MJX's scalar-heavy fusions into code ~40x slower
# than its older loop emitters: one slot's `mjx.kinematics` 32 ms against 0.83 ms a call, the
# agreement test's 8 squares 75 s against 0.7 s of stepping (2026-12-07; BENCHMARKS.md, "MJX on
# the CPU"). Set per program, so that the CPU engine's compiled control pass keeps its code.
CPU_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False}


def jit(fun: Callable, **kwargs) -> Callable:
    """`jax.jit` of an MJX function, with `CPU_COMPILER_OPTIONS` when JAX runs on the CPU."""
    if jax.default_backend() == "cpu":
        given = kwargs.get("compiler_options") or {}
        kwargs["compiler_options"] = {**CPU_COMPILER_OPTIONS, **given}
    return jax.jit(fun, **kwargs)


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
    board_pos3, board_quat = board_pose(
        specs.board_pos, specs.board_yaw, specs.board_height, specs.board_tilt
    )
    hole_origin, hole_axis = hole_frame(specs)
    dz, tilt_x, tilt_y = specs.grasp_error.T
    peg_pos = np.stack([zeros, zeros, dz], axis=-1)
    peg_quat = np.stack(
        [scene.grasp_quat(float(a), float(b)) for a, b in zip(tilt_x, tilt_y, strict=True)]
    )
    goal_pos, goal_rot = goal_pose(specs.hole_est_pos, specs.hole_est_yaw)
    sp = sensor_params(specs, config)
    return dict(
        **{f"sensor_{name}": value for name, value in sp._asdict().items()},
        board_pos3=board_pos3,
        board_quat=board_quat,
        peg_pos=peg_pos,
        peg_quat=peg_quat,
        friction=np.asarray(specs.friction, dtype=np.float64),
        q0=np.asarray(specs.q0, dtype=np.float64),
        goal_pos=goal_pos,
        goal_rot=goal_rot,
        hole_origin=hole_origin,
        hole_axis=hole_axis,
        size=np.asarray(specs.size, dtype=np.float64),
        angular_range=np.asarray(specs.angular_range, dtype=np.float64),
        k_t=params.k_t,
        k_theta=params.k_theta,
        compliance=params.compliance,
        **(
            {}
            if params.search is None
            else {f"search_{k}": v for k, v in params.search._asdict().items() if v is not None}
        ),  # fmt: skip
    )


class _Program:
    """The compiled trial loop for one scene (a part: shape, size, hole scale)."""

    def __init__(self, model: mujoco.MjModel, config: TrialConfig, batch: int, recycle_every: int):
        self.ids = ids = scene.scene_ids(model)
        self.mx = mjx.put_model(model)
        self.config = config
        self.batch = batch
        self.recycle_every = recycle_every
        basis = fitted_basis(config.movement)
        self.basis = Basis(*(jnp.asarray(a) for a in basis))
        self.control = control_config(config, jnp)
        self.qpos_adr = jnp.asarray(ids.qpos_adr)
        self.geoms = jnp.asarray(np.concatenate([ids.peg_geoms, ids.board_geoms]))
        self.run = jit(self._run)

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

    def _measure(self, m, d) -> period.PeriodMeasurement:
        """What the period reads of one slot, after the position and velocity stages."""
        ids = self.ids
        tcp_pos = d.site_xpos[ids.tcp_site]
        jacp, jacr = mjx.jac(m, d, tcp_pos, ids.wrist3_body)
        jdp, jdr = jac_dot(m, d, tcp_pos, ids.wrist3_body)
        force = d.sensordata[ids.ft_force_adr : ids.ft_force_adr + 3]
        torque = d.sensordata[ids.ft_torque_adr : ids.ft_torque_adr + 3]
        return period.PeriodMeasurement(
            qvel=d.qvel,
            tcp_pos=tcp_pos,
            tcp_rot=d.site_xmat[ids.tcp_site].reshape(3, 3),
            tip_pos=d.site_xpos[ids.tip_site],
            ft=jnp.concatenate([force, torque]),
            ft_rot=d.site_xmat[ids.ft_site].reshape(3, 3),
            ft_pos=d.site_xpos[ids.ft_site],
            jac=jnp.concatenate([jacp.T, jacr.T], axis=0),
            jdot_qdot=jnp.concatenate([jdp.T, jdr.T], axis=0) @ d.qvel,
            mass=mjx.full_m(m, d),
            bias=scene.bias_torque(d.qfrc_bias, d.qfrc_passive, ids.dof_adr),
        )

    def _init(self, inp):
        """Data at rest at q0 under gravity compensation, the tare, and the trial's constants."""
        cfg = self.config
        fields = {k: inp[k] for k in _MODEL_FIELDS}
        m = self._slot_model(fields)
        d = mjx.make_data(m)
        d = d.replace(qpos=d.qpos.at[self.qpos_adr].set(inp["q0"]))

        def compensated(_, d):  # forward, then the torque that holds the arm at rest
            d = mjx.forward(m, d)
            return d.replace(ctrl=scene.bias_torque(d.qfrc_bias, d.qfrc_passive, self.ids.dof_adr))

        # twice: the second forward runs under gravity compensation (its torque is the first's:
        # the same pose at rest); one traced forward where two were compiled
        d = jax.lax.fori_loop(0, 2, compensated, d)
        meas = self._measure(m, d)
        y0 = start_state(inp["goal_pos"], inp["goal_rot"], meas.tcp_pos, meas.tcp_rot)
        params = ControllerParams(inp["k_t"], inp["k_theta"], inp["compliance"])
        search = None
        if "search_movement_s" in inp:
            search = SearchValues(**{k: inp[f"search_{k}"] for k in LEARNED})
        search = for_part(cfg.search, search, cfg.movement.duration, inp["size"],
                          inp["angular_range"])  # fmt: skip
        skill = make_skill(params, inp["goal_pos"], inp["goal_rot"], y0, cfg.dmp.tau, search)
        sp = sensor.SensorParams(*(inp[f"sensor_{name}"] for name in sensor.SensorParams._fields))
        consts = period.make_consts(skill, sp, meas.ft, inp["hole_origin"], inp["hole_axis"],
                                    inp["size"], meas.tip_pos)  # fmt: skip
        state = period.start(cfg, consts)
        end = period.Ends(*(jnp.zeros((), bool),) * 4)
        outcome = period.result(cfg, consts, state, meas.tip_pos, end)
        return d, dict(fields=fields, consts=consts, state=state, ended=jnp.zeros((), bool),
                       outcome=outcome)  # fmt: skip

    def _step(self, d, slot):
        """One control period of one slot (`period.period`); ended slots keep their outcome."""
        cfg, state = self.config, slot["state"]
        m = self._slot_model(slot["fields"])
        d = step1(m, d)
        meas = self._measure(m, d)
        end, new, u, _ = period.period(cfg, self.control, self.basis, slot["consts"], state, meas)
        ended_now = ~slot["ended"] & end.ended
        live = ~(slot["ended"] | ended_now)
        outcome = period.result(cfg, slot["consts"], state, meas.tip_pos, end)
        d = step2(m, d.replace(ctrl=jnp.where(live, u, 0.0)))

        def pick(mask, a, b):
            return jax.tree.map(lambda x, y: jnp.where(mask, x, y), a, b)

        return d, dict(
            slot,
            state=pick(live, new, state),  # carried state advances only while the trial runs
            ended=slot["ended"] | ended_now,
            outcome=pick(ended_now, outcome, slot["outcome"]),
        )

    # --- the batch ----------------------------------------------------------------------------
    def _run(self, inputs: dict):
        """Outcomes of all n trials of `inputs` (leading dim n), b slots recycled until done."""
        n = inputs["q0"].shape[0]
        b = self.batch
        init = jax.jit(jax.vmap(self._init))  # traced once, for its shapes and in `reload`
        step = jax.vmap(self._step)

        def take(indices):
            safe = jnp.minimum(indices, n - 1)
            return jax.tree.map(lambda a: a[safe], inputs)

        # Every slot starts ended and empty; the first chunk loads it.
        shapes = jax.eval_shape(init, take(jnp.arange(b)))
        d, slot = jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), shapes)
        slot = dict(slot, ended=jnp.ones(b, bool))
        index = jnp.full(b, n)  # index n: no spec (writes to it are dropped)
        out = jax.tree.map(lambda x: jnp.zeros((n, *x.shape[1:]), x.dtype), slot["outcome"])
        state = (d, slot, index, jnp.asarray(0), out)

        def chunk(state):
            d, slot, index, next_index, out = state
            # Slots whose trial ended write their outcome and take the next spec.
            dest = jnp.where(slot["ended"], index, n)
            out = jax.tree.map(lambda o, v: o.at[dest].set(v, mode="drop"), out, slot["outcome"])
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
def _program(part: tuple[str, float, float], config: TrialConfig, batch: int, recycle_every: int):
    return _Program(scene.load_model(*part), config, batch, recycle_every)


def run_on_device(
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
    keys = [  # the part (shape, size, hole scale) of each trial: one scene each
        (constants.SHAPES[int(s)], round(float(z), 9), round(float(h), 9))
        for s, z, h in zip(specs.shape_id, specs.size, specs.hole_scale, strict=True)
    ]
    out_arrays: dict[str, np.ndarray] = {}
    for key in sorted(set(keys)):
        rows = np.array([i for i, k in enumerate(keys) if k == key])
        b = min(batch or 256, len(rows))
        program = _program(key, config, b, recycle_every)
        inputs = {k: jnp.asarray(v[rows]) for k, v in inputs_all.items()}
        out = jax.device_get(program.run(inputs))
        for name, value in out._asdict().items():
            if name not in out_arrays:
                out_arrays[name] = np.zeros((n, *value.shape[1:]), value.dtype)
            out_arrays[name][rows] = value
        if progress is not None:
            progress(len(rows))
    if not out_arrays:  # no trials
        return TrialResult.concat([])
    steps = out_arrays["steps"].astype(np.int64)
    return TrialResult(**dict(out_arrays, steps=steps, time_s=steps * config.timestep))
