"""The CPU engine's lanes: trials stepped together on C MuJoCo, their periods batched in NumPy.

A lane (`Lane`) runs up to `slots` trials together on the `sims.Sims` of the scenes it meets.
One control period of a lane is one `Sims.step` per scene for its live simulations (C, without
the GIL), then one NumPy pass over every live trial: the bound fields are gathered, the tcp
Jacobian and its derivative computed from them (`jacobian.jacobians`), and `period.ends` and
`period.advance` run on every live row at once, no per-trial Python. The torques go to `ctrl`.

A slot whose trial ends takes the next trial at once (`scene.start_trial` on a scratch model and
MjData, the integration state and model fields copied in, mj_forward), so cost follows the
simulated time actually used. Live trials are rows [0, n), sorted by scene and simulation; a
trial's constants and state (`period.TrialConsts`, `period.TrialState`) move with it when rows
are re-sorted. Lanes run in Python threads: while one steps in C, another runs its NumPy pass.
A trial's arithmetic does not depend on its lane, row, batch or thread count, so results are
bit-identical whatever the threads, slots and batch threads (tested).

Profiling: `run_in_threads(..., profile=f)` calls `f(stage, seconds)` in the lane's thread for each
stage of `PROFILE_STAGES` as it ends (wall time, `time.perf_counter`); without it the lanes read
no clock. It only reads the clock: the results are the same with it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from mjx_peg.array_api import tree_map
from mjx_peg.cores import cores
from mjx_peg.engines import interrupt, period, sims
from mjx_peg.engines.jacobian import jacobians
from mjx_peg.engines.trial import (
    TrialConfig,
    TrialResult,
    control_config,
    fitted_basis,
    sensor_params,
)
from mjx_peg.errors import UsageError
from mjx_peg.skill import sensor
from mjx_peg.skill.control_step import make_skill, start_state
from mjx_peg.skill.params import ControllerParams
from mjx_peg.skill.search import for_part
from mjx_peg.world import mujoco_log
from mjx_peg.world.task import TrialSpec, goal_pose, hole_frame

# MuJoCo's warnings go where the CLI sent them (its output directory or nowhere), never to
# MUJOCO_LOG.TXT in the working directory: world/mujoco_log.py; here for the worker processes.
mujoco_log.install()

# Rows of one lane. The NumPy pass costs ~300 us per period whatever the batch plus ~2 us per
# trial, so bigger batches amortize it (BENCHMARKS.md); 512 trials of 60 s are ~15 M steps.
SLOTS_PER_THREAD = 512

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


# The stages a profile hook sees (`run_in_threads(profile=...)`), in the order of a period.
PROFILE_STAGES = {
    "measure": "the bound fields of the live rows gathered (`Sims.measure`)",
    "ends": "the end tests (`period.ends`) and the ended trials' results (`period.result`)",
    "load": "new trials into free rows (`scene.start_trial`, mj_forward, constants), rows sorted",
    "jacobians": "the tcp Jacobian and Jd qd from cdof (`jacobian.jacobians`)",
    "advance": "`period.advance`: F/T pipeline, damping, metrics, settle test, controller",
    "observer": "the observer, if any",
    "step": "torques to ctrl and one physics step of each scene's live simulations (C)",
}


def to_result(records: np.ndarray) -> TrialResult:
    """TrialResult from RESULT_DTYPE records in spec order."""
    return TrialResult(**{name: records[name].copy() for name in RESULT_DTYPE.names[1:]})


class Queue:
    """Hands out spec indices, collects results and reports progress (thread-safe)."""

    def __init__(self, n: int, progress: Callable[[int], None] | None):
        self._next, self._n = 0, n
        self._lock = threading.Lock()
        self._progress, self._unreported = progress, 0
        self.records = np.zeros(n, RESULT_DTYPE)
        self._stopped = False

    @property
    def stopped(self) -> bool:
        """No more trials: stopped by the caller, an error, or `interrupt.request()`."""
        return self._stopped or interrupt.requested()

    def take(self) -> int | None:
        with self._lock:
            if self._next >= self._n or self.stopped:
                return None
            self._next += 1
            return self._next - 1

    def finish(self, index: np.ndarray, outcome: period.Outcome, time_s: np.ndarray) -> None:
        """Record the trials `index` (k,) that ended with `outcome` (arrays of k)."""
        records = self.records
        records["index"][index] = index
        records["time_s"][index] = time_s
        for name, value in outcome._asdict().items():
            records[name][index] = value
        with self._lock:
            self._unreported += len(index)

    def flush(self) -> None:
        """Report finished trials (call from the caller's thread)."""
        with self._lock:
            count, self._unreported = self._unreported, 0
        if count and self._progress is not None:
            self._progress(count)

    def stop(self) -> None:
        self._stopped = True


def _rows(tree, index):
    return tree_map(lambda a: a[index], tree)


class Lane:
    """Up to `slots` trials stepped together by one thread; live trials in rows [0, n), sorted by
    (scene, simulation): row i is trial `spec_index[i]`, with `consts[i]` and `state[i]`."""

    def __init__(self, specs, params, config: TrialConfig, slots: int, nsim: dict, kind: tuple,
                 profile: Callable[[str, float], None] | None = None):  # fmt: skip
        self.specs, self.params, self.config = specs, params, config
        self.profile = profile  # profile(stage, seconds), or None: no clock read
        self.basis = fitted_basis(config.movement)
        self.control = control_config(config)
        self.slots = slots
        self.nsim, self.kind = nsim, kind  # simulations per scene; batches' (nthread, persistent)
        self.scenes: list[sims.Sims] = []  # in order of first use
        self._scene_of: dict[tuple, int] = {}
        self.sensor_params = sensor_params(specs, config)  # of every trial, computed once
        self.hole_origin, self.hole_axis = hole_frame(specs)
        self.n = 0
        empty = np.zeros(0, dtype=np.int64)
        self.scene, self.sim, self.spec_index = empty, empty, empty
        self.consts: period.TrialConsts | None = None
        self.state: period.TrialState | None = None
        self.blocks: list[tuple[int, int, np.ndarray]] = []  # per scene: rows a:b, simulations
        self.tip_pos = self.tcp_pos = np.zeros((0, 3))  # of rows [0, n), for observers
        self.measured = None

    @property
    def step(self) -> np.ndarray:
        """(n,) control periods of each live row so far."""
        return self.state.step if self.state is not None else np.zeros(0, dtype=np.int64)

    # -- rows ----------------------------------------------------------------------------------

    def _sims(self, key) -> int:
        k = self._scene_of.get(key)
        if k is None:
            k = self._scene_of[key] = len(self.scenes)
            self.scenes.append(sims.take_sims(key, self.nsim[key], self.kind))
        return k

    def _start(self, index: int):
        """Put trial `index` in a free simulation: (scene, simulation, its TrialConsts)."""
        s, cfg = self.specs, self.config
        k = self._sims(sims.scene_key(s, index))
        scene_sims = self.scenes[k]
        sim = scene_sims.free.pop()
        d = scene_sims.load(sim, s, index)
        goal_pos, goal_rot = goal_pose(
            s.hole_est_pos[index : index + 1], s.hole_est_yaw[index : index + 1]
        )
        tcp = scene_sims.ids.tcp_site
        y0 = start_state(goal_pos[0], goal_rot[0], d.site_xpos[tcp].copy(),
                         d.site_xmat[tcp].reshape(3, 3).copy())  # fmt: skip
        p = self.params
        search = None if p.search is None else tree_map(lambda v: v[index], p.search)
        search = for_part(cfg.search, search, cfg.movement.duration, np.asarray(s.size[index]))
        skill = make_skill(
            ControllerParams(p.k_t[index], p.k_theta[index], p.compliance[index]),
            goal_pos[0],
            goal_rot[0],
            y0,
            cfg.dmp.tau,
            search,
        )
        consts = period.make_consts(
            skill,
            sensor.SensorParams(*(value[index] for value in self.sensor_params)),
            d.sensordata[scene_sims.ft].copy(),
            self.hole_origin[index],
            self.hole_axis[index],
            s.size[index],
            d.site_xpos[scene_sims.ids.tip_site].copy(),
        )
        return k, sim, consts

    def _add(self, indices: list[int], keep: np.ndarray) -> None:
        """Rows `keep` of the live rows and new trials `indices` become the live rows, sorted by
        (scene, simulation); the new trials' simulations run forward (the tare)."""
        started = [self._start(i) for i in indices]
        loaded: dict[int, list[int]] = {}
        for k, sim, _ in started:
            loaded.setdefault(k, []).append(sim)
        for k, new in loaded.items():
            self.scenes[k].forward(np.array(sorted(new), dtype=np.int32))
        scene = np.concatenate([self.scene[keep], [k for k, _, _ in started]]).astype(np.int64)
        sim = np.concatenate([self.sim[keep], [s for _, s, _ in started]]).astype(np.int64)
        spec = np.concatenate([self.spec_index[keep], indices]).astype(np.int64)
        consts, state = self.consts, self.state
        if started:
            new = tree_map(lambda *rows: np.stack(rows), *(c for _, _, c in started))
            fresh = period.start(self.config, new)
            if consts is None:
                consts, state = new, fresh
            else:
                join = lambda a, b: np.concatenate([a[keep], b])  # noqa: E731
                consts, state = tree_map(join, consts, new), tree_map(join, state, fresh)
        elif consts is not None:
            consts, state = _rows(consts, keep), _rows(state, keep)
        order = np.lexsort((sim, scene))
        if not np.array_equal(order, np.arange(len(order))):
            scene, sim, spec = scene[order], sim[order], spec[order]
            consts, state = _rows(consts, order), _rows(state, order)
        self.scene, self.sim, self.spec_index = scene, sim, spec
        self.consts, self.state, self.n = consts, state, len(order)
        self.blocks = []
        for k in range(len(self.scenes)):
            a, b = np.searchsorted(scene, [k, k + 1])
            self.blocks.append((int(a), int(b), sim[a:b].astype(np.int32)))

    # -- one control period ----------------------------------------------------------------------

    def _clock(self) -> float:
        return time.perf_counter() if self.profile is not None else 0.0

    def _lap(self, stage: str, since: float) -> float:
        """With a profile hook, report `stage` as the seconds since `since`; the time now."""
        if self.profile is None:
            return 0.0
        now = time.perf_counter()
        self.profile(stage, now - since)
        return now

    def _measure(self) -> sims.Measured:
        """The bound fields of rows [0, n): one gather per field and scene."""
        parts = [self.scenes[k].measure(ids) for k, (a, b, ids) in enumerate(self.blocks) if b > a]
        if len(parts) == 1:
            return parts[0]
        return sims.Measured(*(np.concatenate(field) for field in zip(*parts, strict=True)))

    def _end_trials(self, source, report: bool) -> sims.Measured | None:
        """Record the trials that ended, refill their rows from `source`; the measurements of
        the live rows, None when none is left."""
        cfg = self.config
        while self.n:
            t = self._clock()
            m = self._measure()
            t = self._lap("measure", t)
            tip = m.site_pos[:, 1]
            # MuJoCo resets MjData (time back to 0) when its accelerations blow up.
            physics_ok = ~(np.abs(m.time - self.state.step * cfg.timestep) > 0.5 * cfg.timestep)
            end = period.ends(cfg, self.consts, self.state, tip, m.qvel, physics_ok)
            rows = np.flatnonzero(end.ended)
            if rows.size == 0:
                self._lap("ends", t)
                return m
            state = _rows(self.state, rows)
            outcome = period.result(cfg, _rows(self.consts, rows), state, tip[rows],
                                    _rows(end, rows))  # fmt: skip
            source.finish(self.spec_index[rows], outcome, state.step * cfg.timestep)
            for i in rows.tolist():
                self.scenes[self.scene[i]].free.append(int(self.sim[i]))
            t = self._lap("ends", t)
            indices = []
            for _ in range(rows.size):
                index = source.take()
                if index is None:
                    break
                indices.append(index)
            keep = np.ones(self.n, dtype=bool)
            keep[rows] = False
            self._add(indices, np.flatnonzero(keep))
            self._lap("load", t)
            if report:
                source.flush()
        return None

    def measurement(self, m: sims.Measured) -> period.PeriodMeasurement:
        """The period's measurement of rows [0, n) from their bound fields."""
        tcp_pos, ft_pos = np.ascontiguousarray(m.site_pos[:, 0]), m.site_pos[:, 2]
        jac, jac_dot = jacobians(m.cdof, m.cdof_dot, m.cvel, m.com, tcp_pos)
        return period.PeriodMeasurement(
            qvel=m.qvel,
            tcp_pos=tcp_pos,
            tcp_rot=np.ascontiguousarray(m.site_rot[:, 0]),
            tip_pos=m.site_pos[:, 1],
            ft=m.ft,
            ft_rot=m.site_rot[:, 1],
            ft_pos=ft_pos,
            jac=jac,
            jdot_qdot=(jac_dot @ m.qvel[..., None])[..., 0],
            mass=m.mass,
            bias=m.bias,
        )

    def advance(self, m: sims.Measured):
        """(state, torques, wrench) of rows [0, n) after this period: `period.advance` on their
        measurement; the lane's state is not changed (but the chatter ring, in place)."""
        t = self._clock()
        meas = self.measurement(m)
        t = self._lap("jacobians", t)
        out = period.advance(self.config, self.control, self.basis, self.consts, self.state, meas)
        self._lap("advance", t)
        return out

    def _control(self, m: sims.Measured, observer) -> None:
        """One period of every live trial: the torques written to ctrl, every simulation
        stepped once."""
        state, torques, wrench = self.advance(m)
        t = self._clock()
        if observer is not None:
            self.tip_pos, self.tcp_pos, self.measured = m.site_pos[:, 1], m.site_pos[:, 0], m
            observer(self, np.arange(self.n), wrench)
            t = self._lap("observer", t)
        self.state = state
        for k, (a, b, ids) in enumerate(self.blocks):
            if b > a:
                self.scenes[k].step(ids, torques[a:b])
        self._lap("step", t)

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
            indices = []
            while len(indices) < self.slots:
                index = source.take()
                if index is None:
                    break
                indices.append(index)
            t = self._clock()
            self._add(indices, np.zeros(0, dtype=np.int64))
            self._lap("load", t)
            while self.n and not source.stopped:
                m = self._end_trials(source, report)
                if m is None:
                    break
                self._control(m, observer)
        finally:
            for scene_sims in self.scenes:
                sims.give_sims(scene_sims)


LANE_STOP_S = 10.0  # a stopped lane ends within one control period; this is a bound


def run_lanes(specs, params, config, threads: int, slots: int, kind: tuple, source,
              observer=None, profile=None) -> None:  # fmt: skip
    """Run `threads` lanes of `slots` rows on the trials `source` hands out, in this process.

    The simulations of this call's scenes are kept for the next call, the others dropped.
    """
    count: dict[tuple, int] = {}
    for index in range(len(specs)):
        key = sims.scene_key(specs, index)
        count[key] = count.get(key, 0) + 1
    nsim = {key: min(slots, c) for key, c in count.items()}
    lanes = [Lane(specs, params, config, slots, nsim, kind, profile) for _ in range(threads)]
    errors: list[BaseException] = []

    def work(lane, report=False):
        try:
            lane.run(source, observer, report)
        except BaseException as exc:  # re-raised in the caller's thread
            errors.append(exc)
            source.stop()

    pool: list[threading.Thread] = []
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
        for t in pool:  # and wait for them: a lane still in MuJoCo at exit would crash it
            t.join(timeout=LANE_STOP_S)
        raise
    source.flush()
    sims.keep_sims(set(count))
    if errors:
        raise errors[0]
    interrupt.check()  # the lanes stopped early: their results are incomplete


def count(name: str, value, default: int) -> int:
    """`value` as a positive integer option called `name`, `default` for None."""
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise UsageError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def run_in_threads(
    specs: TrialSpec,
    params: ControllerParams,
    config: TrialConfig,
    threads: int | None = None,
    slots_per_thread: int | None = None,
    progress: Callable[[int], None] | None = None,
    observer: Callable | None = None,
    batch_threads: int | None = None,
    persistent: bool | None = None,
    profile: Callable[[str, float], None] | None = None,
) -> TrialResult:
    """Every trial of `specs` on `threads` lanes in this process (`mujoco.run_on_cpu`' options;
    params batched and validated)."""
    n = len(specs)
    if observer is not None and threads not in (None, 1):
        raise UsageError("an observer runs in the lane's thread: it needs threads=1")
    default = 1 if observer is not None else cores()
    threads = min(count("threads", threads, default), n)
    batch_threads = count("batch_threads", batch_threads, 1)
    slots = count("slots_per_thread", slots_per_thread, 0) or max(
        1, min(SLOTS_PER_THREAD, -(-n // max(threads, 1)))
    )
    queue = Queue(n, progress)
    kind = (batch_threads, None if persistent is None else bool(persistent))
    if n:
        run_lanes(specs, params, config, threads, slots, kind, queue, observer, profile)
    return to_result(queue.records)
