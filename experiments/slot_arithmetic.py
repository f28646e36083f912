"""Whether a trial's numbers depend on the lane's slot count: whole runs, then one period's row.

    python experiments/slot_arithmetic.py [--trials 300] [--slots 512,256,128,64]
        [--target 297] [--at 1247] [--probe-slots 512]

Runs the first `--trials` trials of `paper-small` 50 mm with `policies/paper` (those of the
published grid, docs/eval/paper_spiral_50mm_small_board) on one lane of the CPU engine's
compiled pass (whatever MJX_PEG_CONTROL_PASS says), once per slot count of `--slots`, and lists
the trials whose results (final tip, peak force, chatter, steps, success) are not bit-identical
to the first count's. Then the period behind such a difference: trial `--target`'s constants,
state and measurement at period `--at` (a run of `--probe-slots` slots), put in every slot of
the compiled period's programs of 32 and 512 slots, and the slots whose alignment and torques
differ from slot 0's, bitwise. Measurements and what they mean: docs/design/compiled_period.md,
"A trial's last bits and its slot".
"""

from __future__ import annotations

import argparse

import jax
import numpy as np

from mjx_peg.engines import compiled, period
from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines.trial import as_controller_params
from mjx_peg.evaluation.config import range_specs
from mjx_peg.evaluation.eval_dir import read_eval_dir
from mjx_peg.evaluation.runner import load_controller
from mjx_peg.world.task import TrialSpec

GRID = "docs/eval/paper_spiral_50mm_small_board"


class _Captured(Exception):
    pass


def paper_small(trials: int):
    """(specs, params, trial config) of the published paper-small grid's first `trials`."""
    config, _ = read_eval_dir(GRID)
    _, controller = load_controller("paper")
    ranges = [range_specs(config, i) for i in range(len(config.ranges))]
    params = np.concatenate([controller(s) for s in ranges])[:trials]
    specs = TrialSpec.concat(ranges).take(np.arange(trials))
    return specs, as_controller_params(params, trials), config.trial_config()


def differing(a, b) -> np.ndarray:
    """Indices of the trials whose results in `a` and `b` are not bit-identical."""
    same = np.all(a.final_tip_pos == b.final_tip_pos, axis=1) & (a.peak_force == b.peak_force)
    same &= (a.chatter == b.chatter) & (a.steps == b.steps) & (a.success == b.success)
    return np.flatnonzero(~same)


def capture(specs, params, config, slots: int, target: int, at: int) -> dict:
    """Trial `target`'s constants (from the programs' buffers), state and measurement at
    period `at`, on one lane of `slots` slots."""
    got = {}

    def observe(lane, rows, wrench):
        row = np.flatnonzero(lane.spec_index == target)
        if row.size and int(lane.step[row[0]]) == at:
            row = int(row[0])
            with jax.enable_x64(True):
                buffers = lane._buffers[0]  # the slots' constants
                got["consts"] = period.tree_map(lambda a: np.asarray(a)[lane.slot[row]], buffers)
            got["state"] = period.tree_map(lambda a: np.asarray(a)[row], lane.state)
            got["m"] = period.tree_map(lambda a: np.asarray(a)[row], lane.measured)
            got["slot"], got["size"] = int(lane.slot[row]), lane.size
            raise _Captured

    try:
        cpu_engine.run_on_cpu(specs, params, config, threads=1, slots_per_thread=slots,
                              observer=observe, compiled=True)  # fmt: skip
    except _Captured:
        return got
    raise SystemExit(f"trial {target} did not reach period {at}")


def every_slot(config, row: dict, size: int) -> tuple[list[int], list[int]]:
    """The slots whose alignment and torques differ from slot 0's with `row` in all `size`."""
    tile = lambda a: np.repeat(np.asarray(a)[None], size, axis=0)  # noqa: E731
    consts, state, m = (period.tree_map(tile, row[k]) for k in ("consts", "state", "m"))
    index = np.arange(size, dtype=np.int32)
    with jax.enable_x64(True):
        state = period.tree_map(
            lambda a: jax.numpy.asarray(a, np.int32 if a.dtype == np.int64 else a.dtype), state
        )
        new, _, _, _, torques, _ = compiled.programs(config).period(
            consts, state, m, index, index, np.ones(size, bool)
        )
        aligned, torques = np.asarray(new.aligned), np.asarray(torques)
    odd = lambda x: [k for k in range(size) if not np.array_equal(x[k], x[0])]  # noqa: E731
    return odd(aligned), odd(torques)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=300)
    p.add_argument("--slots", default="512,256,128,64", help="slot counts per lane, compared")
    p.add_argument("--target", type=int, default=297, help="the trial whose period is probed")
    p.add_argument("--at", type=int, default=1247, help="the period probed")
    p.add_argument("--probe-slots", type=int, default=512, help="the lane's slots for the probe")
    args = p.parse_args(argv)
    specs, params, config = paper_small(args.trials)
    counts = [int(x) for x in args.slots.split(",") if x]
    runs = {s: cpu_engine.run_on_cpu(specs, params, config, threads=1, slots_per_thread=s,
                                     compiled=True)
            for s in counts}  # fmt: skip
    first = runs[counts[0]]
    for s in counts[1:]:
        d = differing(first, runs[s])
        outcomes = int(np.sum(first.success[d] != runs[s].success[d]))
        print(f"{s} slots against {counts[0]}: {d.size} of {args.trials} trials differ "
              f"({', '.join(map(str, d[:12]))}), {outcomes} in outcome")  # fmt: skip
    row = capture(specs, params, config, args.probe_slots, args.target, args.at)
    print(f"trial {args.target} at period {args.at}: slot {row['slot']} of {row['size']}")
    for size in (32, 512):
        aligned, torques = every_slot(config, row, size)
        print(f"  its row in all {size} slots: alignment differs from slot 0 in slots {aligned}, "
              f"torques in {torques}")  # fmt: skip


if __name__ == "__main__":
    main()
