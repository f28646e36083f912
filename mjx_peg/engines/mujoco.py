"""The CPU engine: C MuJoCo with the controller batched in NumPy, one batch per core.

A batch (`_Batch`) steps up to `slots` trials together in one thread. Every control period it
runs `mj_step1` on each live trial (fresh kinematics, mass matrix, bias forces; the force sensor
still holds the previous step's reading, as on a real robot), copies what the controller needs
into preallocated batch arrays, computes all the torques in one batched NumPy call of
`control_step.skill_torque`, then runs `mj_step2`. Live trials occupy rows [0, n) of the batch, so
the controller sees only them; a row whose trial ends takes the next trial at once, so cost
follows the simulated time actually used.

The Python part of a step holds the GIL, so threads cannot share out the cores: `workers`
processes (`_pool.py`, started once and reused) each run a batch; `workers=1` runs in the calling
process. A trial's arithmetic does not depend on its batch, row or process, so results are
bit-identical whatever `workers`, `threads` and `slots_per_thread`. Environments (a private model
copy and MjData per scene) are pooled and reused across trials and calls.
"""

from __future__ import annotations

import collections
import os
import threading
from collections.abc import Callable
from typing import NamedTuple

import mujoco
import numpy as np

from mjx_peg.engines import _pool
from mjx_peg.engines._pool import RESULT_DTYPE, to_result
from mjx_peg.engines.trial import (
    TrialConfig,
    TrialResult,
    chatter_of,
    control_config,
    destination,
    fitted_basis,
    is_success,
    sensor_params,
    trial_reward,
)
from mjx_peg.skill import sensor
from mjx_peg.skill.control_step import (
    Measurement,
    Skill,
    external_wrench,
    make_skill,
    skill_torque,
    start_state,
    wrench_to_goal,
)
from mjx_peg.skill.params import ControllerParams
from mjx_peg.world import constants, scene
from mjx_peg.world.task import TrialSpec, goal_pose

# Rows of one batch. The batched controller costs ~200 us per call whatever the batch (its ~100
# NumPy calls) plus ~2 us per trial, so bigger batches amortize it; 128 holds the share of a
# training call (256 trials on 2 cores). See BENCHMARKS.md.
SLOTS_PER_THREAD = 128
DEFAULT_THREADS = 1  # batches per process: the Python part of a step holds the GIL


def available_cores() -> int:
    """Cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


class _Layout(NamedTuple):
    """What a batch needs to know of a scene; the same for every shape and size (checked)."""

    nsite: int
    nsensordata: int
    tcp: int
    ft: int
    tip: int
    wrist3: int
    force_adr: int
    torque_adr: int


# Arrays of a batch with one row per trial (moved with their trial when rows are compacted).
_ROW_ARRAYS = (
    "goal_pos goal_rot y0 k_y d_y compliance tare board_pos size start_distance peak_force step "
    "spec_index jac jac_dot mass qvel bias sim_time site_pos site_mat sensor "
    "s_seed s_hold s_delay s_alpha s_noise s_bias s_history s_filtered coupled "
    "chatter_ring axial stop"
).split()


# The controller's inputs: views of a batch's live rows.
_Live = collections.namedtuple(
    "_Live",
    "goal_pos goal_rot y0 k_y d_y compliance tcp_pos tcp_rot jac jac_dot qvel mass bias force "
    "torque tare ft_rot ft_pos step peak_force s_seed s_hold s_delay s_alpha s_noise s_bias "
    "s_history s_filtered coupled chatter_ring axial stop",
)


class _Env:
    """A private model copy (board, grasp and friction change per trial) and its MjData, with
    views of the MjData fields a batch reads bound once (each attribute access builds an array)."""

    def __init__(self, key: tuple[str, float]):
        self.key = key
        self.model = m = scene.load_model(*key)  # an independent copy
        self.data = d = mujoco.MjData(m)
        self.ids = ids = scene.scene_ids(m)
        assert m.nv == 6 and np.all(ids.dof_adr == np.arange(6)), "the arm must be all the dofs"
        assert m.site_bodyid[ids.tcp_site] == ids.wrist3_body, "tcp must be on the wrist-3 body"
        self.layout = _Layout(m.nsite, m.nsensordata, ids.tcp_site, ids.ft_site, ids.tip_site,
                              ids.wrist3_body, ids.ft_force_adr, ids.ft_torque_adr)  # fmt: skip
        self.site_xpos, self.site_xmat, self.sensordata = d.site_xpos, d.site_xmat, d.sensordata
        self.qpos, self.qvel, self.ctrl = d.qpos, d.qvel, d.ctrl
        self.qfrc_bias, self.qfrc_passive = d.qfrc_bias, d.qfrc_passive
        self.tcp_pos = self.site_xpos[ids.tcp_site]


# Environments not in use, by scene key: kept across calls so that no model is rebuilt.
_FREE_ENVS: dict[tuple[str, float], list[_Env]] = {}
_FREE_LOCK = threading.Lock()


def _take_env(key: tuple[str, float]) -> _Env:
    with _FREE_LOCK:
        free = _FREE_ENVS.get(key)
        if free:
            return free.pop()
    return _Env(key)


def _give_env(env: _Env) -> None:
    with _FREE_LOCK:
        _FREE_ENVS.setdefault(env.key, []).append(env)


def _keep_envs(keys: set) -> None:
    """Drop the free environments of scenes other than `keys` (~0.8 MB each)."""
    with _FREE_LOCK:
        for key in set(_FREE_ENVS) - keys:
            del _FREE_ENVS[key]


def _scene_key(specs: TrialSpec, index: int) -> tuple[str, float]:
    return constants.SHAPES[int(specs.shape_id[index])], float(specs.size[index])


class _Queue:
    """In-process hand-out of spec indices, results and progress (thread-safe)."""

    def __init__(self, n: int, progress: Callable[[int], None] | None):
        self._next, self._n = 0, n
        self._lock = threading.Lock()
        self._progress, self._unreported = progress, 0
        self.records = np.zeros(n, RESULT_DTYPE)
        self.stopped = False

    def take(self, wait: bool = True) -> int | None:
        with self._lock:
            if self._next >= self._n or self.stopped:
                return None
            self._next += 1
            return self._next - 1

    def finish(self, record: tuple) -> None:
        self.records[record[0]] = record
        with self._lock:
            self._unreported += 1

    def flush(self) -> None:
        with self._lock:
            count, self._unreported = self._unreported, 0
            if count and self._progress is not None:
                self._progress(count)

    def stop(self) -> None:
        self.stopped = True


class _Batch:
    """Up to `slots` trials stepped together by one thread; live trials in rows [0, n).

    Row i: `current[i]` (model, data, ids), `spec_index[i]`, `step[i]`, `tip_pos[i]`, ...
    """

    def __init__(self, specs: TrialSpec, params: ControllerParams, config: TrialConfig, slots: int):
        self.specs, self.params, self.config = specs, params, config
        self.basis = fitted_basis(config.dmp)
        self.slots = b = slots
        self.keys = {_scene_key(specs, 0)}  # scenes this batch used
        probe = _take_env(_scene_key(specs, 0))
        _give_env(probe)
        self.layout = lay = probe.layout
        self.envs: list[_Env | None] = [None] * b
        self.current: list[tuple | None] = [None] * b
        self._sense_args: list[tuple | None] = [None] * b
        self._step_args: list[tuple | None] = [None] * b
        eye = np.eye(3)
        # Per-trial constants.
        self.goal_pos, self.goal_rot = np.zeros((b, 3)), np.tile(eye, (b, 1, 1))
        self.y0, self.k_y, self.d_y = np.zeros((b, 6)), np.ones((b, 6)), np.ones((b, 6))
        self.compliance, self.tare = np.zeros((b, 6, 6)), np.zeros((b, 6))
        self.board_pos, self.size = np.zeros((b, 2)), np.ones(b)
        self.start_distance, self.peak_force = np.ones(b), np.zeros(b)
        self.step, self.spec_index = np.zeros(b, dtype=np.int64), np.full(b, -1)
        # Per-step measurements: written by MuJoCo (jacobians, mass matrix) or copied.
        self.jac, self.jac_dot = np.zeros((b, 6, 6)), np.zeros((b, 6, 6))
        self.mass = np.tile(np.eye(6), (b, 1, 1))
        self.qvel, self.bias, self.sim_time = np.zeros((b, 6)), np.zeros((b, 6)), np.zeros(b)
        self.site_pos = np.zeros((b, lay.nsite, 3))
        self.site_mat = np.tile(eye.ravel(), (b, lay.nsite, 1))
        self.sensor = np.zeros((b, lay.nsensordata))
        # The F/T pipeline (skill/sensor.py): per-trial constants and carried state; the compliance
        # damping's low-pass; the contact metrics.
        hist = config.sensor.max_delay_steps + 1
        self.s_seed, self.s_hold = np.zeros(b, np.uint32), np.ones(b, np.int32)
        self.s_delay, self.s_alpha = np.zeros(b, np.int32), np.zeros(b)
        self.s_noise, self.s_bias = np.zeros((b, 6)), np.zeros((b, 6))
        self.s_history, self.s_filtered = np.zeros((b, hist, 6)), np.zeros((b, 6))
        self.coupled = np.zeros((b, 6))
        self.chatter_ring, self.axial = np.zeros((b, config.chatter_steps)), np.zeros(b)
        self.stop = np.zeros(b, dtype=bool)
        self.coupling_pole = config.coupling_pole
        self.sensor_params = sensor_params(specs, config)  # every trial's, indexed at _load
        self._rows = [getattr(self, name) for name in _ROW_ARRAYS]
        # Views into the copies.
        self.tcp_pos, self.tip_pos = self.site_pos[:, lay.tcp], self.site_pos[:, lay.tip]
        self.ft_pos = self.site_pos[:, lay.ft]
        self.tcp_rot = self.site_mat[:, lay.tcp].reshape(b, 3, 3)
        self.ft_rot = self.site_mat[:, lay.ft].reshape(b, 3, 3)
        self.force = self.sensor[:, lay.force_adr : lay.force_adr + 3]
        self.torque = self.sensor[:, lay.torque_adr : lay.torque_adr + 3]
        assert np.shares_memory(self.tcp_rot, self.site_mat), "rotations must be views"
        self.control = control_config(config)
        self._views: tuple = (0, ())

    # -- rows ----------------------------------------------------------------------------------

    def _bind(self, row: int, env: _Env | None) -> None:
        """Point `row` at `env`: the arguments of its per-step MuJoCo calls and copies."""
        self.envs[row] = env
        if env is None:
            self.current[row] = self._sense_args[row] = self._step_args[row] = None
            return
        m, d = env.model, env.data
        self.current[row] = (m, d, env.ids)
        jac, jac_dot = self.jac[row], self.jac_dot[row]
        self._sense_args[row] = (
            m, d, jac[:3], jac[3:], jac_dot[:3], jac_dot[3:], env.tcp_pos, self.mass[row],
            self.site_pos[row], env.site_xpos, self.site_mat[row], env.site_xmat,
            self.qvel[row], env.qvel, self.bias[row], env.qfrc_bias, env.qfrc_passive,
            self.sensor[row], env.sensordata,
        )  # fmt: skip
        self._step_args[row] = (m, d, env.ctrl)

    def _compact(self, n: int, free: list[int]) -> int:
        """Move the last live rows into the free rows among [0, n); the new n."""
        last = n - 1
        for hole in sorted(free):
            while last >= 0 and self.envs[last] is None:
                last -= 1
            if hole > last:
                break
            for a in self._rows:
                a[hole] = a[last]
            self._bind(hole, self.envs[last])
            self._bind(last, None)
        while last >= 0 and self.envs[last] is None:
            last -= 1
        return last + 1

    def _load(self, row: int, index: int) -> None:
        """Start trial `index` in `row`: place board and peg, start pose, tare the sensor."""
        s, cfg, lay = self.specs, self.config, self.layout
        key = _scene_key(s, index)
        self.keys.add(key)
        env = _take_env(key)
        if env.layout != lay:
            raise ValueError(f"scene {key} has layout {env.layout}, not {lay}")
        m, d, ids = env.model, env.data, env.ids
        scene.start_trial(m, d, ids, s.board_pos[index], s.board_yaw[index],
                          s.grasp_error[index], s.friction[index], s.q0[index])  # fmt: skip
        sd = env.sensordata
        self.tare[row, :3] = sd[lay.force_adr : lay.force_adr + 3]
        self.tare[row, 3:] = sd[lay.torque_adr : lay.torque_adr + 3]
        goal_pos, goal_rot = goal_pose(
            s.hole_est_pos[index : index + 1], s.hole_est_yaw[index : index + 1]
        )
        tcp_pos = env.site_xpos[lay.tcp].copy()
        tcp_rot = env.site_xmat[lay.tcp].reshape(3, 3).copy()
        y0 = start_state(goal_pos[0], goal_rot[0], tcp_pos, tcp_rot)
        p = self.params
        skill = make_skill(
            ControllerParams(p.k_t[index], p.k_theta[index], p.compliance[index]),
            goal_pos[0],
            goal_rot[0],
            y0,
            cfg.dmp.tau,
        )
        self.goal_pos[row], self.goal_rot[row] = skill.goal_pos, skill.goal_rot
        self.y0[row], self.k_y[row], self.d_y[row] = skill.y0, skill.k_y, skill.d_y
        self.compliance[row] = skill.compliance
        self.board_pos[row], self.size[row] = s.board_pos[index], s.size[index]
        tip = env.site_xpos[lay.tip]
        self.start_distance[row] = np.linalg.norm(tip - destination(s.board_pos[index]))
        self.peak_force[row] = 0.0
        for name, value in zip(("s_seed", "s_hold", "s_delay", "s_alpha", "s_noise", "s_bias"),
                               self.sensor_params, strict=True):  # fmt: skip
            getattr(self, name)[row] = value[index]
        self.s_history[row], self.s_filtered[row], self.coupled[row] = 0.0, 0.0, 0.0
        self.chatter_ring[row], self.axial[row], self.stop[row] = 0.0, 0.0, False
        self.step[row] = 0
        self.spec_index[row] = index
        self._bind(row, env)

    def _finish(self, row: int, success: bool, unstable: bool, sink) -> None:
        steps, tip = self.step[row], self.tip_pos[row].copy()
        stop = bool(self.stop[row])
        success = success and not unstable and not stop
        reward = trial_reward(
            np.asarray(success), tip, self.board_pos[row], self.start_distance[row],
            self.config.reward,
        )  # fmt: skip
        chatter = float(chatter_of(self.chatter_ring[row], steps)[0])
        sink.finish((self.spec_index[row], success, steps * self.config.timestep, tip,
                     self.peak_force[row], reward, unstable, steps, chatter, stop))  # fmt: skip
        _give_env(self.envs[row])
        self._bind(row, None)
        self.spec_index[row] = -1

    # -- one control period ----------------------------------------------------------------------

    def _sense(self, rows) -> None:
        """mj_step1 and copy what the controller needs into the batch arrays."""
        step1, jac_site = mujoco.mj_step1, mujoco.mj_jacSite
        jac_dot, full_m = mujoco.mj_jacDot, mujoco.mj_fullM
        subtract, sim_time, args = np.subtract, self.sim_time, self._sense_args
        tcp, wrist3 = self.layout.tcp, self.layout.wrist3
        for i in rows:
            (m, d, jl, ja, jdl, jda, p, mass, sp, xpos, sm, xmat, qv, qvel, bias, qfrc_bias,
             qfrc_passive, sensor, sensordata) = args[i]  # fmt: skip
            step1(m, d)
            jac_site(m, d, jl, ja, tcp)
            jac_dot(m, d, jdl, jda, p, wrist3)
            full_m(m, d, mass)
            sp[:] = xpos
            sm[:] = xmat
            qv[:] = qvel
            subtract(qfrc_bias, qfrc_passive, out=bias)  # h: Coriolis, gravity, joint damping
            sensor[:] = sensordata
            sim_time[i] = d.time

    def _ended(self, n: int):
        """success, unstable, ended: (n,) bool of the live rows."""
        cfg, dt = self.config, self.config.timestep
        tip, step = self.tip_pos[:n], self.step[:n]
        success = is_success(tip, self.board_pos[:n], self.size[:n], cfg.success_height)
        # Too fast, NaN or infinite joint speeds fail the speed test alike.
        ok = (np.abs(self.qvel[:n]).max(axis=-1) < cfg.max_joint_speed) & np.isfinite(tip).all(-1)
        # MuJoCo resets MjData (time back to 0) when its accelerations blow up.
        unstable = ~ok | (np.abs(self.sim_time[:n] - step * dt) > 0.5 * dt)
        stop = self.stop[:n]  # set by the previous period's sensed force
        success = success & ~stop
        return success, unstable, success | unstable | stop | (step >= cfg.max_steps)

    def _end_trials(self, n: int, source) -> int:
        """Finish the trials that ended, refill their rows from `source`; the new n."""
        while True:
            success, unstable, ended = self._ended(n)
            rows = np.flatnonzero(ended)
            if rows.size == 0:
                return n
            free = []
            for i in rows.tolist():
                self._finish(i, bool(success[i]), bool(unstable[i]), source)
                index = source.take()
                if index is None:
                    free.append(i)
                else:
                    self._load(i, index)
                    self._sense((i,))  # checked (step 0) on the next pass
            source.flush()
            n = self._compact(n, free)

    def _live(self, n: int) -> _Live:
        """The controller's inputs: views of rows [0, n), rebuilt only when n changes."""
        if self._views[0] != n:
            self._views = (n, _Live(*(getattr(self, k)[:n] for k in _Live._fields)))
        return self._views[1]

    def _sense_wrench(self, v: _Live) -> np.ndarray:
        """The wrench the controller sees (goal frame, at the tcp) for the live rows `v`: the F/T
        pipeline, the compliance damping's low-pass, and the contact metrics on the way."""
        true = external_wrench(v.force, v.torque, v.tare)  # sensor frame
        params = sensor.SensorParams(v.s_seed, v.s_hold, v.s_delay, v.s_alpha, v.s_noise, v.s_bias)
        sensed, state = sensor.step(
            params, sensor.SensorState(v.s_history, v.s_filtered), true, v.step
        )
        v.s_history[:], v.s_filtered[:] = state.history, state.filtered
        force = np.linalg.norm(sensed[:, :3], axis=-1)
        np.maximum(v.peak_force, force, out=v.peak_force)
        np.logical_or(v.stop, force > self.config.max_tool_force, out=v.stop)
        # Chatter of the true axial force: goal z of the world force.
        axial = np.einsum("bi,bij,bj->b", v.goal_rot[:, :, 2], v.ft_rot, true[:, :3])
        later = v.step >= 1
        rows = np.flatnonzero(later)
        v.chatter_ring[rows, v.step[rows] % v.chatter_ring.shape[1]] = np.abs(
            axial[rows] - v.axial[rows]
        )
        v.axial[:] = axial
        wrench = wrench_to_goal(sensed, v.ft_rot, v.ft_pos - v.tcp_pos, v.goal_rot)
        a = self.coupling_pole
        v.coupled[:] = a * v.coupled + (1.0 - a) * wrench
        return v.coupled

    def run(self, source, observer: Callable | None = None) -> None:
        """Step until `source` runs dry; `observer(batch, rows, wrench)` sees every step."""
        cfg = self.config
        n = 0
        while n < self.slots:
            index = source.take(wait=n == 0)  # start with the trials at hand
            if index is None:
                break
            self._load(n, index)
            n += 1
        step2, step_args = mujoco.mj_step2, self._step_args
        while n:
            self._sense(range(n))
            n = self._end_trials(n, source)
            if not n:
                return
            v = self._live(n)
            wrench = self._sense_wrench(v)
            if observer is not None:
                observer(self, np.arange(n), wrench)
            meas = Measurement(
                t=v.step * cfg.timestep,
                tcp_pos=v.tcp_pos,
                tcp_rot=v.tcp_rot,
                jac=v.jac,
                jdot_qdot=(v.jac_dot @ v.qvel[..., None])[..., 0],
                qvel=v.qvel,
                mass=v.mass,
                bias=v.bias,
                wrench=wrench,
            )
            skill = Skill(v.goal_pos, v.goal_rot, v.y0, v.k_y, v.d_y, v.compliance)
            torques = skill_torque(self.control, skill, self.basis, meas)
            torques = np.where(np.isfinite(torques), torques, 0.0)
            for i in range(n):
                m, d, ctrl = step_args[i]
                ctrl[:] = torques[i]
                step2(m, d)
            np.add(v.step, 1, out=v.step)


def run_batches(specs, params, config, threads: int, slots: int, source, observer=None) -> None:
    """Run `threads` batches of `slots` rows on the trials `source` hands out, in this process.

    The environments of this call's scenes are kept for the next call, the others dropped.
    """
    batches = [_Batch(specs, params, config, slots) for _ in range(threads)]
    errors: list[BaseException] = []

    def work(batch):
        try:
            batch.run(source, observer)
        except BaseException as exc:  # re-raised in the caller's thread
            errors.append(exc)
            source.stop()

    if threads == 1:
        work(batches[0])
    else:
        pool = [threading.Thread(target=work, args=(b,), daemon=True) for b in batches]
        for t in pool:
            t.start()
        for t in pool:
            t.join()
    _keep_envs(set().union(*(b.keys for b in batches)))
    if errors:
        raise errors[0]


def run_trials(
    specs: TrialSpec,
    params: ControllerParams,
    config: TrialConfig,
    threads: int | None = None,
    slots_per_thread: int | None = None,
    progress: Callable[[int], None] | None = None,
    observer: Callable | None = None,
    workers: int | None = None,
) -> TrialResult:
    """Run every trial of `specs` with per-trial `params` (batched, validated) on C MuJoCo.

    workers: processes (default: every core this process may use, at most one per trial);
    1 runs the trials in this process. threads: batches per process (default 1).
    slots_per_thread: rows per batch (default: SLOTS_PER_THREAD, or fewer to spread the trials
    over every batch). progress(count) is called as trials finish. observer(batch, rows, wrench),
    if given, is called every control period with a batch, its live rows and their wrenches
    (for demos and benchmarks); it runs in this process, so workers must be 1, its default then.
    """
    n = len(specs)
    threads = _count("threads", threads, DEFAULT_THREADS)
    if observer is not None and workers not in (None, 1):
        raise ValueError("an observer runs in this process: it needs workers=1")
    default = 1 if observer is not None else available_cores()
    workers = min(_count("workers", workers, default), -(-n // threads))
    slots = _count("slots_per_thread", slots_per_thread, 0) or max(
        1, min(SLOTS_PER_THREAD, -(-n // (workers * threads)))
    )
    if workers > 1:
        return _pool.run(specs, params, config, workers, threads, slots, progress)
    queue = _Queue(n, progress)
    run_batches(specs, params, config, threads, slots, queue, observer)
    return to_result(queue.records)


def _count(name: str, value, default: int) -> int:
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)
