"""The CPU engine's control period compiled by XLA: the NumPy pass's functions, jitted.

One call per period runs `period.ends`, `period.result`, `period.advance` and
`sims.period_measurement` (the Jacobians) in float64 over a lane's slots: each trial keeps a slot
of XLA's buffers (its constants and state, updated in place) from start to end; the measurement
goes in, the torques and the ended trials' outcomes come out. A slot freed takes its next trial
after the call, whose first period is the lane's next. float64 holds in the lane's thread only
(`jax.enable_x64`): a Brax PPO run in float32 in the same process keeps float32. Design and
measurements: docs/design/compiled_period.md.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from mjx_peg.array_api import tree_map
from mjx_peg.engines import lanes, period, sims
from mjx_peg.engines.trial import TrialConfig, control_config, fitted_basis
from mjx_peg.skill.control_step import Basis

LOAD_ROWS = 16  # new trials' constants per load call


def slot_count(slots: int) -> int:
    """The compiled programs' slot count for a lane of `slots` rows: 32 or 64, then a multiple
    of 64 (few sizes to compile, little padding). A trial's numbers do not depend on the count,
    but for one in the program's last four slots, where a few operations round otherwise
    (docs/design/compiled_period.md, "A trial's last bits and its slot")."""
    if slots <= 32:
        return 32
    return -(-slots // 64) * 64


def drained_count(rows: int, size: int) -> int:
    """The slot count a lane of `size` slots moves to when only `rows` are left (its source has
    run dry): the power of two that holds them (at least 32) once it is a quarter of `size` or
    less, else `size`. A period costs about its slot count, whatever the rows left."""
    fit = max(32, 1 << max(rows - 1, 0).bit_length())
    return fit if fit <= size // 4 else size


def _start(config: TrialConfig, consts: period.TrialConsts) -> period.TrialState:
    """`period.start` with strong types (its infinities are weakly typed: each program would be
    traced again for the state its previous call returned)."""
    return tree_map(lambda a: jnp.asarray(a, dtype=a.dtype), period.start(config, consts))


def _gather(tree, index):
    return tree_map(lambda a: a[index], tree)


class Programs:
    """The jitted programs of one trial config (each compiled once per slot count)."""

    def __init__(self, config: TrialConfig):
        self.config = config
        with jax.enable_x64(True):
            self.control = control_config(config, jnp)
            self.basis = Basis(*(jnp.asarray(a) for a in fitted_basis(config.movement)))
        self.period = jax.jit(self._period, donate_argnums=(1,))
        self.load = jax.jit(self._load, donate_argnums=(0, 1))
        self.take = jax.jit(lambda tree, slots: jax.tree.map(lambda a: a[slots], tree))

    def _period(self, consts, state, rows: sims.Measured, row_of_slot, slot_of_row, live):
        """One period of every slot: (state, ended, steps, outcome, torques, wrench), all but
        the state in row order. ended: `period.ends` of the slots with a trial (`live`, (S,)
        bool); steps: their periods before this one; outcome: `period.result` (zeros where no
        trial ends); torques, wrench: `period.advance` (a slot's state without a trial, or whose
        trial ended, is never read again)."""
        cfg = self.config
        m = tree_map(lambda a: a[row_of_slot], rows)
        ok = sims.physics_ok(m.time, state.step, cfg.timestep)
        end = period.ends(cfg, consts, state, m.site_pos[:, 1], m.qvel, ok)
        ended = end.ended & live
        meas = sims.period_measurement(m)
        new, torques, wrench = period.advance(cfg, self.control, self.basis, consts, state, meas,
                                              going=~ended)  # fmt: skip

        def outcome():
            # The ring after the advance: a trial that ended kept its own (read before the write,
            # the ring, updated in place, would be copied twice each period).
            before = state._replace(chatter_ring=new.chatter_ring)
            return period.result(cfg, consts, before, m.site_pos[:, 1], end)

        none = lambda: tree_map(jnp.zeros_like, jax.eval_shape(outcome))  # noqa: E731
        done = jax.lax.cond(jnp.any(ended), outcome, none)
        rowwise = lambda a: a[slot_of_row]  # noqa: E731
        return (new, rowwise(ended), rowwise(state.step), tree_map(rowwise, done),
                rowwise(torques), rowwise(wrench))  # fmt: skip

    def _load(self, consts, state, slots, new):
        """consts, state with trials of constants `new` (LOAD_ROWS rows) at their start in
        `slots` (LOAD_ROWS,); a slot index past the end drops its row."""
        put = lambda a, v: a.at[slots].set(v, mode="drop")  # noqa: E731
        return tree_map(put, consts, new), tree_map(put, state, _start(self.config, new))

    def empty(self, like: period.TrialConsts, size: int):
        """consts, state of `size` slots without trials, shaped as the rows of `like`."""
        consts = tree_map(lambda a: jnp.zeros((size, *a.shape[1:]), a.dtype), like)
        state = tree_map(lambda a: jnp.array(a, copy=True), _start(self.config, consts))
        return consts, state  # a buffer each: the programs donate them


@functools.lru_cache(maxsize=32)
def programs(config: TrialConfig) -> Programs:
    return Programs(config)


class CompiledLane(lanes.Lane):
    """A lane whose periods run compiled (`Programs`): rows as in `lanes.Lane`, row i's trial
    in slot `slot[i]` of the programs' buffers."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.size = slot_count(self.slots)
        self.programs = programs(self.config)
        self.slot = np.zeros(0, dtype=np.int64)
        self._free_slots = list(range(self.size - 1, -1, -1))
        self._buffers = None  # (consts, state) of every slot
        self._index = None  # (row_of_slot, slot_of_row, live): (S,) each
        self._steps = np.zeros(0, dtype=np.int64)
        self._observed = None

    @property
    def step(self) -> np.ndarray:
        """(n,) control periods of each live row before this period (observers)."""
        return self._steps[: self.n]

    @property
    def state(self) -> period.TrialState | None:
        """The rows' state before this period (observers; a copy from XLA's buffers)."""
        return self._observed

    @state.setter
    def state(self, value) -> None:  # the base class's; the slots hold the state
        pass

    def _join(self, new: list, keep: np.ndarray, order: np.ndarray) -> None:
        assert len(new) <= len(self._free_slots), "more trials than free slots"
        slots = np.concatenate([self.slot[keep], [self._free_slots.pop() for _ in new]])
        self.slot = slots.astype(np.int64)[order]
        size = drained_count(len(self.slot), self.size) if not new else self.size
        with jax.enable_x64(True):
            if new:
                self._load(new, slots[len(keep) :])
            if size < self.size:  # the rows left into slots 0..n-1 of fewer slots
                take = np.zeros(size, dtype=np.int32)
                take[: len(self.slot)] = self.slot
                self._buffers = self.programs.take(self._buffers, take)
                self.size, self.slot = size, np.arange(len(self.slot))
                self._free_slots = list(range(size - 1, len(self.slot) - 1, -1))
            self._index = self._slot_index()

    def _slot_index(self):
        """(row_of_slot, slot_of_row, live) of the rows' slots, (S,) each."""
        n = len(self.slot)
        row_of_slot = np.zeros(self.size, dtype=np.int32)
        row_of_slot[self.slot] = np.arange(n)
        slot_of_row = np.zeros(self.size, dtype=np.int32)
        slot_of_row[:n] = self.slot
        live = np.zeros(self.size, dtype=bool)
        live[self.slot] = True
        return tuple(jnp.asarray(a) for a in (row_of_slot, slot_of_row, live))

    def _load(self, new: list, slots: np.ndarray) -> None:
        """The constants of new trials into their slots, their state at the start."""
        p = self.programs
        if self._buffers is None:
            self._buffers = p.empty(tree_map(lambda a: np.asarray(a)[None], new[0]), self.size)
        for start in range(0, len(new), LOAD_ROWS):
            part = new[start : start + LOAD_ROWS]
            index = np.full(LOAD_ROWS, self.size, dtype=np.int32)  # past the end: dropped
            index[: len(part)] = slots[start : start + len(part)]
            part = part + [part[0]] * (LOAD_ROWS - len(part))
            rows = tree_map(lambda *a: np.stack(a), *part)
            self._buffers = p.load(*self._buffers, index, rows)

    def _measure(self, size: int = 0) -> sims.Measured:
        return super()._measure(self.size)

    def measurement(self, m: sims.Measured) -> period.PeriodMeasurement:
        return tree_map(lambda a: a[: self.n], super().measurement(m))

    def advance(self, m: sims.Measured):
        """(ended, steps, outcome, torques, wrench) of rows [0, n): one compiled period (the
        slots' state moves on, in XLA's buffers); outcome as XLA arrays of every row."""
        t = self._clock()
        with jax.enable_x64(True):
            consts, state = self._buffers
            if self.observing:
                self._observed = tree_map(lambda a: np.asarray(a)[self.slot], state)
            state, *out = self.programs.period(consts, state, m, *self._index)
            self._buffers = consts, state
            ended, steps, outcome, torques, wrench = out
            n = self.n
            ended, steps = np.asarray(ended)[:n], np.asarray(steps)
            torques, wrench = np.asarray(torques)[:n], np.asarray(wrench)[:n]
        self._lap("advance", t)
        return ended, steps, outcome, torques, wrench

    def _end_trials(self, source, report: bool) -> sims.Measured | None:
        """The measurements of the live rows, None when none is left (their ends are tested
        in the compiled period)."""
        if not self.n:
            return None
        t = self._clock()
        m = self._measure()
        self._lap("measure", t)
        return m

    def _control(self, m: sims.Measured, observer) -> None:
        """One period: the compiled period of every live row; the rows that go on stepped once,
        those that ended recorded and refilled (their new trials step from the next period)."""
        ended, self._steps, outcome, torques, wrench = self.advance(m)
        t = self._clock()
        rows, going = np.flatnonzero(ended), np.flatnonzero(~ended)
        if observer is not None and going.size:
            self.tip_pos, self.tcp_pos, self.measured = m.site_pos[:, 1], m.site_pos[:, 0], m
            observer(self, going, wrench)
            t = self._lap("observer", t)
        for k, (a, b, ids) in enumerate(self.blocks):
            on = going[(going >= a) & (going < b)]
            if on.size:
                self.scenes[k].step(ids[on - a], torques[on])
        t = self._lap("step", t)
        if rows.size:
            with jax.enable_x64(True):
                done = tree_map(lambda x: np.asarray(x)[rows], outcome)
            self._free_slots.extend(self.slot[rows].tolist())
            self._finish(self.source, rows, done, done.steps, self.report, t)

    def run(self, source, observer=None, report: bool = False) -> None:
        self.source, self.report, self.observing = source, report, observer is not None
        super().run(source, observer, report)
