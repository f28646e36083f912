"""The failure taxonomy (`mjx_peg.evaluation.taxonomy`) of one batch of trials, per shape.

    python experiments/failures.py --linear-mm 4 --angular-deg 6 --trials 120 --seed 123
    python experiments/failures.py --linear-mm 0 --angular-deg 0 --shape circle,square,triangle \\
        --trials 60 --seed 7 --list          # the zero-error trials, each failure listed

Prints per shape the success rate and the Markdown table of the failures; --list adds one line
per failure (index, class, where the tip ended, time); --out saves specs and results (npz).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from ablations import add_skill_option, chosen  # experiments/ablations.py

from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.evaluation import taxonomy
from mjx_peg.evaluation.runner import load_controller
from mjx_peg.world.constants import GRASP_MODELS
from mjx_peg.world.task import TaskConfig, sample_trials


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", default="baseline", help="run directory, or baseline")
    p.add_argument("--shape", default="circle,square")
    p.add_argument("--size-mm", type=float, default=50.0)
    p.add_argument("--linear-mm", type=float, default=4.0)
    p.add_argument("--angular-deg", type=float, default=6.0)
    p.add_argument("--grasp-model", default="board", choices=GRASP_MODELS)
    add_skill_option(p)
    p.add_argument("--trials", type=int, default=60, help="per shape")
    p.add_argument("--seed", type=int, default=123)
    p.add_argument("--time-limit", type=float, default=60.0)
    p.add_argument("--list", action="store_true", help="one line per failure")
    p.add_argument("--out", help="npz of the specs and results")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    _, controller = load_controller(args.policy)
    skill = chosen(args.skill, args.policy)
    config = TrialConfig(time_limit_s=args.time_limit, search=skill.config)
    saved = {}
    for shape in args.shape.split(","):
        task = TaskConfig.from_mm_deg((shape,), args.size_mm, args.linear_mm, args.angular_deg,
                                      grasp_model=args.grasp_model)  # fmt: skip
        specs = sample_trials(task, args.seed, args.trials)
        result = run_trials(specs, controller(specs), "mujoco", config)
        arrays = result.to_arrays()
        rows = taxonomy.table(specs, arrays, config.time_limit_s, config.timestep)
        print(f"## {shape}: {result.summary()}\n")
        print(taxonomy.markdown(rows, len(specs)))
        if args.list:
            label = taxonomy.classify(specs, arrays)
            depth, lateral = taxonomy.tip_at_hole(specs, result.final_tip_pos)
            for i in np.flatnonzero(label >= 0):
                name = taxonomy.CLASSES[label[i]]
                print(f"  trial {i:3d}: {name:18s} tip {1e3 * lateral[i]:5.1f} mm from the axis, "
                      f"{1e3 * depth[i]:6.1f} mm deep, {result.time_s[i]:5.1f} s, peak "
                      f"{result.peak_force[i]:4.0f} N")  # fmt: skip
            print()
        saved.update({f"{shape}/spec/{k}": v for k, v in specs.to_arrays().items()})
        saved.update({f"{shape}/result/{k}": v for k, v in arrays.items()})
    if args.out:
        np.savez(args.out, **saved)
    return 0


if __name__ == "__main__":
    sys.exit(main())
