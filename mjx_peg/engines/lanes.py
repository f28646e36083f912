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
are re-sorted. Lanes run in Python threads (`engines/threaded.py`): while one steps in C, another
runs its NumPy pass. A trial's arithmetic does not depend on its lane, row, batch or thread
count, so results are bit-identical whatever the threads, slots and batch threads (tested). The
compiled pass (`engines/compiled.py`) is not quite so: a trial in one of the last four slots of
its program computes a few operations in another rounding (docs/design/compiled_period.md, "A
trial's last bits and its slot").

Profiling: `threaded.run_in_threads(..., profile=f)` calls `f(stage, seconds)` in the lane's
thread for each stage of `PROFILE_STAGES` as it ends (wall time, `time.perf_counter`); without it
the lanes read no clock. It only reads the clock: the results are the same with it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from mjx_peg.array_api import tree_map
from mjx_peg.engines import interrupt, period, sims
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
from mjx_peg.world.task import goal_pose, hole_frame

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


# The stages a profile hook sees (`threaded.run_in_threads(profile=...)`), in the order of a period.
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
        search = for_part(cfg.search, search, cfg.movement.duration, np.asarray(s.size[index]),
                          np.asarray(s.angular_range[index]))  # fmt: skip
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
        order = np.lexsort((sim, scene))
        self._join([c for _, _, c in started], keep, order)
        self.scene, self.sim, self.spec_index = scene[order], sim[order], spec[order]
        self.n = len(order)
        self.blocks = []
        for k in range(len(self.scenes)):
            a, b = np.searchsorted(self.scene, [k, k + 1])
            self.blocks.append((int(a), int(b), self.sim[a:b].astype(np.int32)))

    def _join(self, new: list, keep: np.ndarray, order: np.ndarray) -> None:
        """The rows' constants and state: rows `keep`, then the new trials' (constants `new`, at
        their start), in `order`."""
        consts, state = self.consts, self.state
        if new:
            added = tree_map(lambda *rows: np.stack(rows), *new)
            fresh = period.start(self.config, added)
            if consts is None:
                consts, state = added, fresh
            else:
                join = lambda a, b: np.concatenate([a[keep], b])  # noqa: E731
                consts, state = tree_map(join, consts, added), tree_map(join, state, fresh)
        elif consts is not None:
            consts, state = _rows(consts, keep), _rows(state, keep)
        if consts is not None and not np.array_equal(order, np.arange(len(order))):
            consts, state = _rows(consts, order), _rows(state, order)
        self.consts, self.state = consts, state

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

    def _measure(self, size: int = 0) -> sims.Measured:
        """The bound fields of rows [0, n), then copies of the last up to `size` rows: one gather
        per field and scene."""
        blocks = [(k, ids) for k, (a, b, ids) in enumerate(self.blocks) if b > a]
        pads = [0] * (len(blocks) - 1) + [max(0, size - self.n)]
        parts = [
            self.scenes[k].measure(ids, pad) for (k, ids), pad in zip(blocks, pads, strict=True)
        ]
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
            physics_ok = sims.physics_ok(m.time, self.state.step, cfg.timestep)
            end = period.ends(cfg, self.consts, self.state, tip, m.qvel, physics_ok)
            rows = np.flatnonzero(end.ended)
            if rows.size == 0:
                self._lap("ends", t)
                return m
            state = _rows(self.state, rows)
            outcome = period.result(cfg, _rows(self.consts, rows), state, tip[rows],
                                    _rows(end, rows))  # fmt: skip
            self._finish(source, rows, outcome, state.step, report, t)
        return None

    def _finish(self, source, rows: np.ndarray, outcome: period.Outcome, steps, report: bool,
                t: float) -> None:  # fmt: skip
        """Record the trials at `rows` that ended (`outcome`, after `steps` periods), free their
        simulations, and fill their rows with new trials from `source`."""
        source.finish(self.spec_index[rows], outcome, steps * self.config.timestep)
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

    def measurement(self, m: sims.Measured) -> period.PeriodMeasurement:
        """The period's measurement of rows [0, n) from their bound fields."""
        return sims.period_measurement(m)

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


def count(name: str, value, default: int) -> int:
    """`value` as a positive integer option called `name`, `default` for None."""
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise UsageError(f"{name} must be a positive integer, got {value!r}")
    return int(value)
