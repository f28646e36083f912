"""The CPU engine: C MuJoCo stepped by its own thread pool (`mujoco.batch`), the controller
batched in NumPy over every live trial at once.

A lane (`_Lane`) runs up to `slots` trials together. Each scene (shape, size) it meets is a
`mujoco.batch.Batch` (`_Sims`) whose model fields that `scene.start_trial` edits per trial
(board pose, grasp, friction) are expanded per simulation; small batches keep one MjData per
simulation (persistent), larger ones one per C thread (PERSISTENT_MAX_SIMS). One control period
of a lane is

1. per scene, one `Batch.step(ids, stage=mjSTAGE_VEL)` for its live simulations, in C without
   the GIL: the torques written to `ctrl` are applied (mj_step2), then the position and velocity
   stages run at the new state (mj_step1), so kinematics, mass matrix and bias forces are fresh
   while the F/T reading (an acceleration-stage sensor) is one step old, as on a real robot;
2. one NumPy pass over every live trial of the lane, no per-trial Python: the bound fields are
   gathered (site poses, joint velocities, bias forces, sensors, the sparse mass matrix, cdof,
   cdof_dot, cvel), the tcp Jacobian and its derivative are computed from them (`jacobians`,
   MuJoCo's mj_jac and mj_jacDot in NumPy), then the end checks (success, joint speeds,
   protective stop, settled), the F/T pipeline (`skill.sensor`) and the compliance damping's
   low-pass on the tared reading with the contact metrics (`_Lane._sense`), the settle test and
   `skill.control_step.skill_torque`, whose torques go to `ctrl`.

A slot whose trial ends takes the next trial at once (`scene.start_trial` on a scratch model and
MjData, the integration state and model fields copied in, mj_forward), so cost follows the
simulated time actually used. Live trials occupy rows [0, n) of the lane, sorted by scene and
simulation; everything a trial carries from one period to the next (the skill's constants, the
sensor's parameters and state, the damping's filter, the metrics, the settle test) lives in
per-row arrays (`_ROW_ARRAYS`) that move with it when rows are re-sorted. The sensor's random
draws are counter-based functions of the trial's own `sensor_seed` and period index. Lanes run
in Python threads (`threads`, default every core): while one steps in C, another runs its NumPy
pass. A trial's arithmetic does not depend on its lane, row, batch or thread count, so results
are bit-identical whatever `threads`, `slots_per_thread` and `batch_threads` (tested), and
bit-identical to the engine before (one MjData per trial with mj_step1, mj_jacSite, mj_jacDot,
mj_fullM and mj_step2; BENCHMARKS.md).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from typing import NamedTuple

import mujoco
import mujoco.batch
import numpy as np

from mjx_peg.engines.trial import (
    SettleState,
    TrialConfig,
    TrialResult,
    chatter_of,
    control_config,
    destination,
    fitted_basis,
    is_settled,
    is_success,
    sensor_params,
    settle_close,
    settle_observe,
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
from mjx_peg.world import constants, mujoco_log, scene
from mjx_peg.world.task import TrialSpec, goal_pose

# MuJoCo's warnings go where the CLI sent them (its output directory or nowhere), never to
# MUJOCO_LOG.TXT in the working directory: world/mujoco_log.py; here for the worker processes.
mujoco_log.install()

# Rows of one lane. The NumPy pass costs ~300 us per period whatever the batch plus ~2 us per
# trial, so bigger batches amortize it (BENCHMARKS.md); 512 trials of 60 s are ~15 M steps.
SLOTS_PER_THREAD = 512
# A persistent batch (one MjData per simulation) continues each step from the position and
# velocity stages the controller read, but its simulations' memory leaves the caches as the batch
# grows. CPU time per step on this 2-core machine (the baseline jammed in the hole, 512 states):
# persistent 5.8-6.3 us at 64-256 simulations, 6.8-7.4 at 512; one MjData per C thread (which
# recomputes those stages) 8.7-9.0 at any size; mj_step on one MjData 5.4. Under other jobs'
# load the persistent batch of 512 fell to 11.3 us (the non-persistent one: 9.2). Batches of up
# to this many simulations are persistent (results are the same either way).
PERSISTENT_MAX_SIMS = 512
STAGE_VEL = int(mujoco.mjtStage.mjSTAGE_VEL)
STAGE_ACC = int(mujoco.mjtStage.mjSTAGE_ACC)
STATE = mujoco.mjtState.mjSTATE_INTEGRATION
# The model fields scene.start_trial writes; each simulation of a batch has its own values.
TRIAL_MODEL_FIELDS = ("body_pos", "body_quat", "geom_friction")

# One finished trial.
RESULT_DTYPE = np.dtype(
    [
        ("index", "<i8"),
        ("success", "?"),
        ("time_s", "<f8"),
        ("final_tip_pos", "<f8", (3,)),
        ("peak_force", "<f8"),
        ("reward", "<f8"),
        ("unstable", "?"),
        ("steps", "<i8"),
        ("settled", "?"),
        ("chatter", "<f8"),
        ("protective_stop", "?"),
    ]
)


def available_cores() -> int:
    """Cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def to_result(records: np.ndarray) -> TrialResult:
    """TrialResult from RESULT_DTYPE records in spec order."""
    return TrialResult(**{name: records[name].copy() for name in RESULT_DTYPE.names[1:]})


# -- kinematics from MuJoCo's bound fields ------------------------------------------------------


_NEXT, _LAST = np.array([1, 2, 0]), np.array([2, 0, 1])


def _cross(a, b):
    """(3, ...) a x b of vectors along the first axis (component-major, so that NumPy runs long
    loops), each component computed as MuJoCo's mju_cross so that the bits match:
    (a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0)."""
    return a[_NEXT] * b[_LAST] - a[_LAST] * b[_NEXT]


def jacobians(cdof, cdof_dot, cvel, com, point):
    """jac, jac_dot (n, 6, nv): [linear; angular] Jacobian of world `point` (n, 3) on a body whose
    dof chain is every dof, and its time derivative: MuJoCo's mj_jac and mj_jacDot, operation for
    operation.

    cdof, cdof_dot: (n, nv, 6) dof motion axes and their derivatives, [angular, linear] about
    `com` (n, 3), the subtree centre of mass of the body's root; cvel: (n, 6) the body's velocity
    in the same form.
    """
    n, nv = cdof.shape[:2]
    axes = np.ascontiguousarray(cdof.transpose(2, 0, 1))  # (6, n, nv)
    axes_dot = np.ascontiguousarray(cdof_dot.transpose(2, 0, 1))
    offset = np.ascontiguousarray((point - com).T)  # (3, n)
    vel = np.ascontiguousarray(cvel.T)
    point_vel = vel[3:] - _cross(offset, vel[:3])  # mju_transformSpatial
    offset = np.repeat(offset[:, :, None], nv, axis=2)  # (3, n, nv)
    point_vel = np.repeat(point_vel[:, :, None], nv, axis=2)
    jac, jac_dot = np.empty((6, n, nv)), np.empty((6, n, nv))
    np.add(axes[3:], _cross(axes[:3], offset), out=jac[:3])
    jac[3:] = axes[:3]
    np.add(axes_dot[3:], _cross(axes_dot[:3], offset), out=jac_dot[:3])
    jac_dot[:3] += _cross(axes[:3], point_vel)
    jac_dot[3:] = axes_dot[:3]
    return (
        np.ascontiguousarray(jac.transpose(1, 0, 2)),
        np.ascontiguousarray(jac_dot.transpose(1, 0, 2)),
    )


def _dense_mass_index(m: mujoco.MjModel) -> np.ndarray:
    """(nv * nv,) index into MjData.M (the sparse lower triangle) of each dense entry."""
    index = np.full((m.nv, m.nv), -1)
    for row in range(m.nv):
        for adr in range(m.M_rowadr[row], m.M_rowadr[row] + m.M_rownnz[row]):
            col = m.M_colind[adr]
            index[row, col] = index[col, row] = adr
    assert (index >= 0).all(), "the arm's mass matrix must be dense (one chain)"
    return index.ravel()


def _chain_is_every_dof(m: mujoco.MjModel, body: int) -> bool:
    body = m.body_weldid[body]
    dofs, i = [], m.body_dofadr[body] + m.body_dofnum[body] - 1
    while i >= 0:
        dofs.append(i)
        i = m.dof_parentid[i]
    return sorted(dofs) == list(range(m.nv))


class _Measured(NamedTuple):
    """What a control period reads of its live trials (one row each)."""

    time: np.ndarray  # (n,) MjData.time
    qvel: np.ndarray  # (n, 6)
    site_pos: np.ndarray  # (n, 3, 3) tcp, tip, ft
    site_rot: np.ndarray  # (n, 2, 3, 3) tcp, ft
    ft: np.ndarray  # (n, 6) force, torque sensor readings (site frame)
    mass: np.ndarray  # (n, 6, 6)
    bias: np.ndarray  # (n, 6) qfrc_bias - qfrc_passive
    cdof: np.ndarray  # (n, 6, 6)
    cdof_dot: np.ndarray  # (n, 6, 6)
    cvel: np.ndarray  # (n, 6) of the tcp's body
    com: np.ndarray  # (n, 3) subtree com of its root


class _Sims:
    """One scene's simulations: a `mujoco.batch.Batch` of `nsim` and its bound fields.

    Used by one lane at a time (a Batch serves one Python thread).
    """

    def __init__(self, key: tuple[str, float], nsim: int, nthread: int, persistent: bool = True):
        self.key, self.nsim, self.kind = key, nsim, (nthread, persistent)
        self.model = m = scene.load_model(*key)
        self.trial_model = scene.load_model(*key)  # start_trial edits it; its fields are copied
        self.trial_data = mujoco.MjData(self.trial_model)
        self.ids = ids = scene.scene_ids(m)
        assert m.nv == 6 and np.all(ids.dof_adr == np.arange(6)), "the arm must be all the dofs"
        assert np.all(ids.actuator_ids == np.arange(6)), "ctrl must be in joint order"
        assert m.site_bodyid[ids.tcp_site] == ids.wrist3_body, "tcp must be on the wrist-3 body"
        assert _chain_is_every_dof(m, ids.wrist3_body), "the tcp must move with every dof"
        self.batch = b = mujoco.batch.Batch(m, nsim, nthread=nthread, persistent=persistent)
        self.fields = {name: b.expand(name) for name in TRIAL_MODEL_FIELDS}
        self.state = b.state
        self.time, self.qvel, self.ctrl = b.bind("time"), b.bind("qvel"), b.bind("ctrl")
        self.qpos = b.bind("qpos")
        self.site_xpos, self.site_xmat = b.bind("site_xpos"), b.bind("site_xmat")
        self.sensordata, self.mass = b.bind("sensordata"), b.bind("M")
        self.cdof, self.cdof_dot = b.bind("cdof"), b.bind("cdof_dot")
        self.cvel, self.subtree_com = b.bind("cvel"), b.bind("subtree_com")
        self.qfrc_bias, self.qfrc_passive = b.bind("qfrc_bias"), b.bind("qfrc_passive")
        self.sites = np.array([ids.tcp_site, ids.tip_site, ids.ft_site])
        self.ft = np.r_[ids.ft_force_adr : ids.ft_force_adr + 3,
                        ids.ft_torque_adr : ids.ft_torque_adr + 3]  # fmt: skip
        self.mass_index = _dense_mass_index(m)
        self.body, self.root = ids.wrist3_body, m.body_rootid[ids.wrist3_body]
        self.free: list[int] = []
        self._view: tuple | None = None

    def reset(self) -> None:
        """Every simulation free (lowest first)."""
        self.free = list(range(self.nsim - 1, -1, -1))

    def load(self, sim: int, specs: TrialSpec, index: int) -> mujoco.MjData:
        """Put trial `index` in simulation `sim`; the scratch MjData at the start (its sensors are
        the tare). The caller runs `forward` on the simulations it loaded."""
        m, d = self.trial_model, self.trial_data
        s = specs
        scene.start_trial(m, d, self.ids, s.board_pos[index], s.board_yaw[index],
                          s.grasp_error[index], s.friction[index], s.q0[index])  # fmt: skip
        for name, values in self.fields.items():
            values[sim] = getattr(m, name)
        mujoco.mj_getState(m, d, self.state[sim], STATE)
        return d

    def forward(self, ids: np.ndarray) -> None:
        """mj_forward at the loaded states (the tare reading), then (persistent batch) the
        position and velocity stages the next step continues from."""
        for stage in (STAGE_ACC, STAGE_VEL)[: 1 + self.kind[1]]:
            try:
                self.batch.forward(ids, stage=stage)
            except mujoco.batch.SimulationError:
                pass  # their time check fails: unstable

    def step(self, ids: np.ndarray, torques: np.ndarray) -> None:
        """Apply `torques` (len(ids), 6) and step simulations `ids` (sorted) once."""
        self.ctrl[ids] = torques
        try:
            self.batch.step(None if len(ids) == self.nsim else ids, stage=STAGE_VEL)
        except mujoco.batch.SimulationError:
            pass  # those simulations kept their state: their time check fails (unstable)

    def measure(self, ids: np.ndarray) -> _Measured:
        """The bound fields of simulations `ids` (sorted): one gather per field (no copy of the
        fields that need none when `ids` are all the simulations)."""
        take = np.take
        if len(ids) == self.nsim:
            rows = lambda a: a  # noqa: E731
        else:
            rows = lambda a: take(a, ids, axis=0)  # noqa: E731
        bias = scene.bias_torque(rows(self.qfrc_bias), rows(self.qfrc_passive), self.ids.dof_adr)
        return _Measured(
            rows(self.time),
            np.ascontiguousarray(rows(self.qvel)),  # a view of the state rows when all
            take(rows(self.site_xpos), self.sites, axis=1),
            take(rows(self.site_xmat), self.sites[[0, 2]], axis=1).reshape(-1, 2, 3, 3),
            take(rows(self.sensordata), self.ft, axis=1),
            take(rows(self.mass), self.mass_index, axis=1).reshape(-1, 6, 6),
            bias,
            rows(self.cdof),
            rows(self.cdof_dot),
            rows(self.cvel[:, self.body]),
            rows(self.subtree_com[:, self.root]),
        )

    def current(self, sim: int) -> tuple:
        """(model, data, ids) of simulation `sim` (copies, reused: for observers). A batch that
        is not persistent keeps only the state: mj_forward recomputes the rest."""
        if self._view is None:
            self._view = (scene.load_model(*self.key), mujoco.MjData(self.model))
        m, d = self._view
        self.batch.get_model(sim, m)
        self.batch.get_data(sim, d)
        if not self.kind[1]:
            mujoco.mj_forward(m, d)
        return m, d, self.ids


# Simulations not in use, by (scene, batch threads): kept across calls so that no batch is rebuilt.
_FREE_SIMS: dict[tuple, list[_Sims]] = {}
_FREE_LOCK = threading.Lock()


def _take_sims(key: tuple[str, float], nsim: int, kind: tuple) -> _Sims:
    """Simulations for `key` from the pool, or new ones; kind: (C threads, persistent or None
    for persistent up to PERSISTENT_MAX_SIMS simulations)."""
    nthread, persistent = kind
    if persistent is None:
        persistent = nsim <= PERSISTENT_MAX_SIMS
    kind = (nthread, persistent)
    with _FREE_LOCK:
        free = _FREE_SIMS.get((key, kind), [])
        fits = [s for s in free if s.nsim >= nsim]
        if fits:
            sims = min(fits, key=lambda s: s.nsim)
            free.remove(sims)
            sims.reset()
            return sims
    sims = _Sims(key, nsim, *kind)
    sims.reset()
    return sims


def _give_sims(sims: _Sims) -> None:
    with _FREE_LOCK:
        _FREE_SIMS.setdefault((sims.key, sims.kind), []).append(sims)


def _keep_sims(keys: set) -> None:
    """Drop the free simulations of scenes other than `keys`."""
    with _FREE_LOCK:
        for cached in [k for k in _FREE_SIMS if k[0] not in keys]:
            del _FREE_SIMS[cached]


def _scene_key(specs: TrialSpec, index: int) -> tuple[str, float]:
    return constants.SHAPES[int(specs.shape_id[index])], float(specs.size[index])


class _Queue:
    """Hands out spec indices, collects results and reports progress (thread-safe)."""

    def __init__(self, n: int, progress: Callable[[int], None] | None):
        self._next, self._n = 0, n
        self._lock = threading.Lock()
        self._progress, self._unreported = progress, 0
        self.records = np.zeros(n, RESULT_DTYPE)
        self.stopped = False

    def take(self) -> int | None:
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
        """Report finished trials (call from the caller's thread)."""
        with self._lock:
            count, self._unreported = self._unreported, 0
        if count and self._progress is not None:
            self._progress(count)

    def stop(self) -> None:
        self.stopped = True


# Arrays of a lane with one row per live trial, moved with their trial when rows are re-sorted:
# the skill's constants, the F/T pipeline's (`s_*`: the trial's SensorParams and SensorState), the
# compliance damping's low-pass (`coupled`), the contact metrics and the settle test's state.
_ROW_ARRAYS = (
    "scene sim goal_pos goal_rot y0 k_y d_y compliance tare board_pos size start_distance "
    "peak_force step spec_index settle_low settle_high settle_last_low settle_last_high matched "
    "s_seed s_hold s_delay s_alpha s_noise s_bias s_history s_filtered coupled chatter_ring axial "
    "stop"
).split()
_SENSOR_PARAMS = ("s_seed", "s_hold", "s_delay", "s_alpha", "s_noise", "s_bias")  # SensorParams


class _Lane:
    """Up to `slots` trials stepped together by one thread; live trials in rows [0, n), sorted by
    (scene, simulation). Row i: `spec_index[i]`, `step[i]`, `goal_pos[i]`, ..."""

    def __init__(self, specs, params, config: TrialConfig, slots: int, nsim: dict, kind: tuple):
        self.specs, self.params, self.config = specs, params, config
        self.basis = fitted_basis(config.dmp)
        self.slots = b = slots
        self.nsim, self.kind = nsim, kind  # simulations per scene; batches' (nthread, persistent)
        self.scenes: list[_Sims] = []  # in order of first use
        self._scene_of: dict[tuple, int] = {}
        eye = np.eye(3)
        self.scene, self.sim = np.zeros(b, dtype=np.int64), np.zeros(b, dtype=np.int64)
        self.goal_pos, self.goal_rot = np.zeros((b, 3)), np.tile(eye, (b, 1, 1))
        self.y0, self.k_y, self.d_y = np.zeros((b, 6)), np.ones((b, 6)), np.ones((b, 6))
        self.compliance, self.tare = np.zeros((b, 6, 6)), np.zeros((b, 6))
        self.board_pos, self.size = np.zeros((b, 2)), np.ones(b)
        self.start_distance, self.peak_force = np.ones(b), np.zeros(b)
        self.step, self.spec_index = np.zeros(b, dtype=np.int64), np.full(b, -1)
        self.settle_low, self.settle_high = np.zeros((b, 10)), np.zeros((b, 10))
        self.settle_last_low, self.settle_last_high = np.zeros((b, 10)), np.zeros((b, 10))
        self.matched = np.zeros(b, dtype=np.int64)
        self._settle = [getattr(self, n) for n in _ROW_ARRAYS if n.startswith("settle_")]
        # The F/T pipeline (skill/sensor.py): each row's SensorParams (from every trial's, computed
        # once) and SensorState; the compliance damping's low-pass of the sensed wrench (goal
        # frame); the contact metrics: a ring of |dF| of the true axial force (chatter), its last
        # value, the protective stop.
        self.sensor_params = sensor_params(specs, config)
        hist = config.sensor.max_delay_steps + 1
        self.s_seed, self.s_hold = np.zeros(b, np.uint32), np.ones(b, np.int32)
        self.s_delay, self.s_alpha = np.zeros(b, np.int32), np.zeros(b)
        self.s_noise, self.s_bias = np.zeros((b, 6)), np.zeros((b, 6))
        self.s_history, self.s_filtered = np.zeros((b, hist, 6)), np.zeros((b, 6))
        self.coupled = np.zeros((b, 6))
        self.chatter_ring, self.axial = np.zeros((b, config.chatter_steps)), np.zeros(b)
        self.stop = np.zeros(b, dtype=bool)
        self._rows = [getattr(self, name) for name in _ROW_ARRAYS]
        self.control = control_config(config)
        self.n = 0
        self.blocks: list[tuple[int, int, np.ndarray]] = []  # per scene: rows a:b, simulations
        self.tip_pos = self.tcp_pos = np.zeros((0, 3))  # of rows [0, n), for observers

    # -- rows ----------------------------------------------------------------------------------

    def _sims(self, key) -> int:
        k = self._scene_of.get(key)
        if k is None:
            k = self._scene_of[key] = len(self.scenes)
            self.scenes.append(_take_sims(key, self.nsim[key], self.kind))
        return k

    def _sort(self, n: int, keep: np.ndarray | None = None) -> None:
        """Rows `keep` (default: [0, n)) become rows [0, len(keep)), sorted by (scene, sim)."""
        rows = np.arange(n) if keep is None else keep
        order = rows[np.lexsort((self.sim[rows], self.scene[rows]))]
        if not np.array_equal(order, np.arange(n)):
            for a in self._rows:
                a[: len(order)] = a[order]
        self.n = n = len(order)
        self.blocks = []
        for k in range(len(self.scenes)):
            a, b = np.searchsorted(self.scene[:n], [k, k + 1])
            self.blocks.append((int(a), int(b), self.sim[a:b].astype(np.int32)))

    def _load(self, row: int, index: int) -> tuple[int, int]:
        """Start trial `index` in `row`; (scene, simulation) to run forward on."""
        s, cfg = self.specs, self.config
        k = self._sims(_scene_key(s, index))
        sims = self.scenes[k]
        sim = sims.free.pop()
        d = sims.load(sim, s, index)
        self.tare[row] = d.sensordata[sims.ft]
        goal_pos, goal_rot = goal_pose(
            s.hole_est_pos[index : index + 1], s.hole_est_yaw[index : index + 1]
        )
        tcp = sims.ids.tcp_site
        y0 = start_state(goal_pos[0], goal_rot[0], d.site_xpos[tcp].copy(),
                         d.site_xmat[tcp].reshape(3, 3).copy())  # fmt: skip
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
        tip = d.site_xpos[sims.ids.tip_site]
        self.start_distance[row] = np.linalg.norm(tip - destination(s.board_pos[index]))
        self.peak_force[row] = 0.0
        for name, value in zip(_SENSOR_PARAMS, self.sensor_params, strict=True):
            getattr(self, name)[row] = value[index]
        self.s_history[row], self.s_filtered[row], self.coupled[row] = 0.0, 0.0, 0.0
        self.chatter_ring[row], self.axial[row], self.stop[row] = 0.0, 0.0, False
        self.step[row] = self.matched[row] = 0
        for a, value in zip(self._settle, (np.inf, -np.inf, np.inf, -np.inf), strict=True):
            a[row] = value
        self.spec_index[row] = index
        self.scene[row], self.sim[row] = k, sim
        return k, sim

    def _finish(self, row: int, m: _Measured, flags, sink) -> None:
        success, unstable, settled = flags
        steps, tip = self.step[row], m.site_pos[row, 1].copy()
        stop = bool(self.stop[row])
        success = success and not unstable and not stop
        chatter = float(chatter_of(self.chatter_ring[row], steps)[0])
        reward = trial_reward(
            np.asarray(success), tip, self.board_pos[row], self.start_distance[row],
            self.config.reward,
        )  # fmt: skip
        sink.finish((self.spec_index[row], success, steps * self.config.timestep, tip,
                     self.peak_force[row], reward, unstable, steps, settled, chatter,
                     stop))  # fmt: skip
        self.scenes[self.scene[row]].free.append(int(self.sim[row]))
        self.spec_index[row] = -1

    # -- one control period ----------------------------------------------------------------------

    def _measure(self) -> _Measured:
        """The bound fields of rows [0, n): one gather per field and scene."""
        parts = [self.scenes[k].measure(ids) for k, (a, b, ids) in enumerate(self.blocks) if b > a]
        if len(parts) == 1:
            return parts[0]
        return _Measured(*(np.concatenate(field) for field in zip(*parts, strict=True)))

    def _ended(self, m: _Measured):
        """success, unstable, settled, ended: (n,) bool of the live rows."""
        n, cfg, dt = self.n, self.config, self.config.timestep
        tip, step = m.site_pos[:, 1], self.step[:n]
        success = is_success(tip, self.board_pos[:n], self.size[:n], cfg.success_height)
        # Too fast, NaN or infinite joint speeds fail the speed test alike.
        ok = (np.abs(m.qvel).max(axis=-1) < cfg.max_joint_speed) & np.isfinite(tip).all(-1)
        # MuJoCo resets MjData (time back to 0) when its accelerations blow up.
        unstable = ~ok | (np.abs(m.time - step * dt) > 0.5 * dt)
        stop = self.stop[:n]  # the protective stop, set by the previous period's sensed force
        success &= ~stop
        settled = is_settled(SettleState(*(None,) * 4, self.matched[:n]), cfg)
        settled &= ~success & ~unstable & ~stop
        ended = success | unstable | stop | settled | (step >= cfg.max_steps)
        return success, unstable, settled, ended

    def _end_trials(self, source, report: bool) -> _Measured | None:
        """Finish the trials that ended, refill their rows from `source`; the measurements of
        the live rows, None when none is left."""
        while self.n:
            m = self._measure()
            success, unstable, settled, ended = self._ended(m)
            rows = np.flatnonzero(ended)
            if rows.size == 0:
                return m
            loaded: dict[int, list[int]] = {}
            keep = np.ones(self.n, dtype=bool)
            for i in rows.tolist():
                self._finish(i, m, (bool(success[i]), bool(unstable[i]), bool(settled[i])), source)
                index = source.take()
                if index is None:
                    keep[i] = False
                    continue
                k, sim = self._load(i, index)
                loaded.setdefault(k, []).append(sim)
            for k, sims in loaded.items():
                self.scenes[k].forward(np.array(sorted(sims), dtype=np.int32))
            if report:
                source.flush()
            self._sort(self.n, np.flatnonzero(keep))
        return None

    def _sense(self, n: int, ft, ft_rot, lever, goal_rot, step) -> np.ndarray:
        """(n, 6) the wrench the compliance sees (goal frame, at the tcp) of rows [0, n): the F/T
        pipeline on the tared reading `ft` (n, 6), then the compliance damping's low-pass; on
        the way the contact metrics (peak sensed force, protective stop, chatter of the true
        axial force). Every row's state advances by one control period."""
        true = external_wrench(ft[:, :3], ft[:, 3:], self.tare[:n])  # sensor frame
        params = sensor.SensorParams(*(getattr(self, k)[:n] for k in _SENSOR_PARAMS))
        state = sensor.SensorState(self.s_history[:n], self.s_filtered[:n])
        sensed, state = sensor.step(params, state, true, step)
        self.s_history[:n], self.s_filtered[:n] = state.history, state.filtered
        force = np.linalg.norm(sensed[:, :3], axis=-1)
        peak, stop = self.peak_force[:n], self.stop[:n]
        np.maximum(peak, force, out=peak)
        np.logical_or(stop, force > self.config.max_tool_force, out=stop)
        # Chatter: |F_k - F_(k-1)| of the true axial force (the world force along goal z), written
        # at k mod W for k >= 1.
        f_world = (ft_rot * true[:, None, :3]).sum(axis=-1)
        axial = (goal_rot[:, :, 2] * f_world).sum(axis=-1)
        rows = np.flatnonzero(step >= 1)
        ring = self.chatter_ring
        ring[rows, step[rows] % ring.shape[1]] = np.abs(axial[rows] - self.axial[rows])
        self.axial[:n] = axial
        wrench = wrench_to_goal(sensed, ft_rot, lever, goal_rot)
        a, coupled = self.config.coupling_pole, self.coupled[:n]
        coupled[...] = a * coupled + (1.0 - a) * wrench
        return coupled

    def _control(self, m: _Measured, observer) -> None:
        """Torques of every live trial, written to ctrl; one step of every simulation."""
        torques = self._torques(m, observer)
        for k, (a, b, ids) in enumerate(self.blocks):
            if b > a:
                self.scenes[k].step(ids, torques[a:b])
        np.add(self.step[: self.n], 1, out=self.step[: self.n])

    def _torques(self, m: _Measured, observer) -> np.ndarray:
        """(n, 6) joint torques of rows [0, n): the control period's NumPy pass (Jacobians, the
        sensed wrench, the settle test, the controller); the physics is not stepped."""
        n, cfg = self.n, self.config
        tcp_pos, tip_pos, ft_pos = m.site_pos[:, 0], m.site_pos[:, 1], m.site_pos[:, 2]
        tcp_rot, ft_rot = m.site_rot[:, 0], m.site_rot[:, 1]
        jac, jac_dot = jacobians(m.cdof, m.cdof_dot, m.cvel, m.com, tcp_pos)
        goal_rot, step = self.goal_rot[:n], self.step[:n]
        wrench = self._sense(n, m.ft, ft_rot, ft_pos - tcp_pos, goal_rot, step)
        t = step * cfg.timestep
        if cfg.end_settled:  # settle_update, the window test only on the rows it concerns
            low, high = self.settle_low[:n], self.settle_high[:n]
            state = settle_observe(
                SettleState(low, high, None, None, None), m.qvel, tcp_pos, wrench
            )
            low[...], high[...] = state.low, state.high
            rows = np.flatnonzero((step + 1) % cfg.settle_steps == 0)
            if rows.size:
                state = SettleState(*(a[rows] for a in self._settle), self.matched[rows])
                for a, value in zip(
                    (*self._settle, self.matched), settle_close(state, step[rows], cfg), strict=True
                ):
                    a[rows] = value
        if observer is not None:
            self.tip_pos, self.tcp_pos, self.measured = tip_pos, tcp_pos, m
            observer(self, np.arange(n), wrench)
        qvel = m.qvel
        meas = Measurement(
            t=t,
            tcp_pos=np.ascontiguousarray(tcp_pos),
            tcp_rot=np.ascontiguousarray(tcp_rot),
            jac=jac,
            jdot_qdot=(jac_dot @ qvel[..., None])[..., 0],
            qvel=qvel,
            mass=m.mass,
            bias=m.bias,
            wrench=wrench,
        )
        skill = Skill(*(a[:n] for a in (self.goal_pos, self.goal_rot, self.y0, self.k_y,
                                         self.d_y, self.compliance)))  # fmt: skip
        torques = skill_torque(self.control, skill, self.basis, meas)
        return np.where(np.isfinite(torques), torques, 0.0)

    @property
    def qpos(self) -> np.ndarray:
        """(n, nq) joint positions of rows [0, n) (a copy; for observers)."""
        parts = [self.scenes[k].qpos[ids] for k, (a, b, ids) in enumerate(self.blocks) if b > a]
        return np.concatenate(parts) if parts else np.zeros((0, 6))

    @property
    def current(self):
        """current[i]: (model, data, ids) of row i's simulation (copies; for observers)."""
        lane = self

        class _Current:
            def __getitem__(self, row):
                return lane.scenes[lane.scene[row]].current(int(lane.sim[row]))

        return _Current()

    def run(self, source, observer: Callable | None = None, report: bool = False) -> None:
        """Step until `source` runs dry; `observer(lane, rows, wrench)` sees every period."""
        try:
            loaded: dict[int, list[int]] = {}
            while self.n < self.slots:
                index = source.take()
                if index is None:
                    break
                k, sim = self._load(self.n, index)
                loaded.setdefault(k, []).append(sim)
                self.n += 1
            for k, sims in loaded.items():
                self.scenes[k].forward(np.array(sorted(sims), dtype=np.int32))
            self._sort(self.n)
            while self.n and not source.stopped:
                m = self._end_trials(source, report)
                if m is None:
                    break
                self._control(m, observer)
        finally:
            for sims in self.scenes:
                _give_sims(sims)


def run_lanes(specs, params, config, threads: int, slots: int, kind: tuple, source,
              observer=None) -> None:  # fmt: skip
    """Run `threads` lanes of `slots` rows on the trials `source` hands out, in this process.

    The simulations of this call's scenes are kept for the next call, the others dropped.
    """
    count: dict[tuple, int] = {}
    for index in range(len(specs)):
        key = _scene_key(specs, index)
        count[key] = count.get(key, 0) + 1
    nsim = {key: min(slots, c) for key, c in count.items()}
    lanes = [_Lane(specs, params, config, slots, nsim, kind) for _ in range(threads)]
    errors: list[BaseException] = []

    def work(lane, report=False):
        try:
            lane.run(source, observer, report)
        except BaseException as exc:  # re-raised in the caller's thread
            errors.append(exc)
            source.stop()

    try:
        if threads == 1:
            work(lanes[0], report=True)
        else:
            pool = [threading.Thread(target=work, args=(lane,), daemon=True) for lane in lanes]
            for t in pool:
                t.start()
            for t in pool:
                while t.is_alive():
                    t.join(timeout=0.05)
                    source.flush()
    except BaseException:  # KeyboardInterrupt: stop the lanes at their next period
        source.stop()
        raise
    source.flush()
    _keep_sims(set(count))
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
    batch_threads: int | None = None,
    persistent: bool | None = None,
    processes: int | None = None,
    ray: str | None = None,
) -> TrialResult:
    """Run every trial of `specs` with per-trial `params` (batched, validated) on C MuJoCo.

    threads: lanes, each a Python thread with its own batches (default: every core this process
    may use, at most one per trial); workers: the same (its name when lanes were processes).
    slots_per_thread: rows per lane (default: SLOTS_PER_THREAD, or fewer to spread the trials
    over every lane). batch_threads: C threads of each lane's batches (default 1).
    persistent: one MjData per simulation (`mujoco.batch.Batch(persistent=True)`: each step
    continues from the position and velocity stages the controller read) or one per C thread
    (a step recomputes them, but its memory stays in the cache); the same results. Default:
    persistent for batches of up to PERSISTENT_MAX_SIMS simulations.
    progress(count) is called in the caller's thread as trials finish. observer(lane, rows,
    wrench), if given, is called every control period with a lane, its live rows and their
    wrenches (for demos and benchmarks); it needs threads=1, its default then.
    processes: run the trials in that many worker processes (`engines/processes.py`: one GIL
    each) of `threads` lanes each (default 1); None (the default): lanes in this process.
    ray: run them on the Ray cluster at this address, one lane per CPU (`engines/ray_pool.py`:
    "auto", "local" or HOST:PORT); the same results.
    """
    n = len(specs)
    if workers is not None and threads is not None and workers != threads:
        raise ValueError(f"threads ({threads}) and workers ({workers}) name the same option")
    threads = threads if threads is not None else workers
    if ray is not None or processes is not None:  # lanes elsewhere: bad values are one error
        for name, value in (("threads", threads), ("slots_per_thread", slots_per_thread),
                            ("batch_threads", batch_threads)):  # fmt: skip
            _count(name, value, 1)  # here, before any worker starts
    if ray is not None:
        if processes is not None or observer is not None or threads not in (None, 1):
            raise ValueError("ray runs one lane per cluster CPU: it takes no processes, "
                             "threads or observer")  # fmt: skip
        from mjx_peg.engines import ray_pool

        return ray_pool.run_trials(
            specs, params, config, ray, progress=progress, slots_per_thread=slots_per_thread,
            batch_threads=batch_threads, persistent=persistent,
        )  # fmt: skip
    if processes is not None:
        processes = _count("processes", processes, 1)
        if observer is not None:
            raise ValueError("an observer runs in the lane's thread: it needs processes=None")
        from mjx_peg.engines import processes as worker_processes

        return worker_processes.run_trials(
            specs, params, config, processes, threads=threads, progress=progress,
            slots_per_thread=slots_per_thread, batch_threads=batch_threads, persistent=persistent,
        )  # fmt: skip
    if observer is not None and threads not in (None, 1):
        raise ValueError("an observer runs in the lane's thread: it needs threads=1")
    default = 1 if observer is not None else available_cores()
    threads = min(_count("threads", threads, default), n)
    batch_threads = _count("batch_threads", batch_threads, 1)
    slots = _count("slots_per_thread", slots_per_thread, 0) or max(
        1, min(SLOTS_PER_THREAD, -(-n // threads))
    )
    queue = _Queue(n, progress)
    kind = (batch_threads, None if persistent is None else bool(persistent))
    run_lanes(specs, params, config, threads, slots, kind, queue, observer)
    return to_result(queue.records)


def _count(name: str, value, default: int) -> int:
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)
