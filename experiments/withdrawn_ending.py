"""The failures an evaluation ran to its time limit, run again: a paired check that ending a
failure once the search has withdrawn the peg (`search.search_withdrawn`) changes no outcome.

    python experiments/withdrawn_ending.py before.npz [--eval DIR] [--policy paper]
        [--successes 40]                                       # at the old commit
    python experiments/withdrawn_ending.py after.npz --compare before.npz

The trials: those of the evaluation `--eval` (its `ranges/`, `config.json`) that failed after
running to the time limit, and its first `--successes` successes, on the C engine with the
evaluation's trial config (`--pass`: the control period's pass, default the engine's). Saves per
trial the outcome, steps, the settled flag, the final tip and its failure class
(`evaluation.taxonomy`); `--compare` prints, against another run of the same trials, the trials
whose outcome or class differs, the physics steps of both, and the largest distance between the
final tips.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from mjx_peg.engines import run_trials
from mjx_peg.evaluation import taxonomy
from mjx_peg.evaluation.config import range_specs
from mjx_peg.evaluation.eval_dir import read_eval_dir
from mjx_peg.evaluation.runner import load_controller
from mjx_peg.world.task import TrialSpec


def chosen_trials(eval_dir: str, successes: int):
    """(config, specs, (range, trial) pairs) of the failures run to the limit and `successes`
    successes of an evaluation."""
    config, _ = read_eval_dir(eval_dir)
    limit = config.trial_config().max_steps
    picked, parts, taken = [], [], 0
    for path in sorted(Path(eval_dir, "ranges").glob("*.npz")):
        index = int(path.stem)
        with np.load(path, allow_pickle=False) as done:
            ran_out = ~done["success"] & (done["steps"] >= limit)
            ok = np.flatnonzero(done["success"])[: max(0, successes - taken)]
        rows = np.union1d(np.flatnonzero(ran_out), ok)
        taken += ok.size
        if rows.size:
            parts.append(range_specs(config, index).take(rows))
            picked += [(index, int(k)) for k in rows]
    return config, TrialSpec.concat(parts), np.array(picked)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", help="npz to write")
    p.add_argument("--eval", default="docs/eval/paper_spiral_50mm_small_board")
    p.add_argument("--policy", default="paper", help="'baseline', a shipped policy or a run")
    p.add_argument("--successes", type=int, default=40)
    p.add_argument("--pass", dest="control_pass", choices=("numpy", "compiled"), default=None)
    p.add_argument("--compare", help="an npz of the same trials written before")
    args = p.parse_args(argv)
    config, specs, picked = chosen_trials(args.eval, args.successes)
    trial = config.trial_config()
    _, controller = load_controller(args.policy)
    options = {} if args.control_pass is None else {"compiled": args.control_pass == "compiled"}
    result = run_trials(specs, controller(specs), engine="mujoco", config=trial, **options)
    arrays = result.to_arrays()
    arrays["class"] = taxonomy.classify(specs, arrays)
    arrays["picked"] = picked
    np.savez(args.out, **arrays)
    names = taxonomy.CLASSES
    counts = {names[c]: int((arrays["class"] == c).sum()) for c in np.unique(arrays["class"])
              if c >= 0}  # fmt: skip
    print(f"{len(specs)} trials of {args.eval}: {int(result.success.sum())} succeeded, "
          f"{int(result.settled.sum())} settled, failures by class {counts}, "
          f"{int(result.steps.sum()):,} physics steps")  # fmt: skip
    if args.compare is None:
        return 0
    with np.load(args.compare, allow_pickle=False) as before:
        if not np.array_equal(before["picked"], picked):
            raise SystemExit(f"--compare: {args.compare} holds other trials")
        differ = np.flatnonzero(before["success"] != result.success)
        moved = np.flatnonzero(before["class"] != arrays["class"])
        gap = np.linalg.norm(before["final_tip_pos"] - result.final_tip_pos, axis=1)
        shorter = np.flatnonzero(before["steps"] != result.steps)
        print(
            f"outcome differs on {differ.size} of {len(specs)} {differ.tolist()}, class on "
            f"{moved.size} {moved.tolist()}; steps on {shorter.size} "
            f"({int(result.success[shorter].sum())} successes); physics steps "
            f"{int(before['steps'].sum()):,} -> {int(result.steps.sum()):,}; final tips at "
            f"most {1e3 * gap.max():.2f} mm apart (median {1e3 * np.median(gap):.3f} mm)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
