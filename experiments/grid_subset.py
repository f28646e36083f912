"""Success and time per quarter of an evaluation's grid on its first trials of each shape per
range, with another policy, skill or search constants: a quick paired check of a change.

    python experiments/grid_subset.py [--eval docs/eval/paper_spiral_50mm_small_board]
        [--per-shape 5] [--policy paper] [--skill spiral] [--search 'NAME=V;...'] [--npz F]

The trials are the evaluation's own (`config.range_specs` of its config.json): the first
`--per-shape` circles and squares (or whatever shapes it has) of each range, on the C engine with
that evaluation's time limit; ranges keep their quarter. Prints per quarter the success over the
trials and the mean over ranges of the mean time of the successes (as `eval.py` does), then
the protective stops, the sensed peak force, chatter and physics steps. docs/design/spiral_timing.md
used it with `--per-shape 5` (1,000 trials of `paper-small`, 125-210 s on 2 cores).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from ablations import ABLATIONS  # experiments/ablations.py
from contact import search_config  # experiments/contact.py

from mjx_peg.engines import run_trials
from mjx_peg.evaluation.config import range_specs
from mjx_peg.evaluation.eval_dir import read_eval_dir
from mjx_peg.evaluation.runner import load_controller
from mjx_peg.evaluation.stats import QUARTERS, quarter_labels
from mjx_peg.world.task import TrialSpec


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--eval", default="docs/eval/paper_spiral_50mm_small_board")
    p.add_argument("--per-shape", type=int, default=5, help="trials of each shape per range")
    p.add_argument("--policy", default="paper", help="'baseline', a shipped policy or a run")
    p.add_argument(
        "--skill",
        default=None,
        choices=tuple(ABLATIONS),
        help="an ablation (experiments/ablations.py); default: the evaluation's",
    )
    p.add_argument("--search", default="", help="SkillConfig constants changed, 'NAME=V;...'")
    p.add_argument("--time-limit", type=float, default=None, help="default: the evaluation's")
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--npz", help="write success, time_s, range, stop, peak force per trial here")
    args = p.parse_args(argv)
    if args.per_shape < 1:
        raise SystemExit(f"--per-shape must be at least 1, got {args.per_shape}")
    try:
        config, _ = read_eval_dir(args.eval)
    except (OSError, ValueError) as e:
        raise SystemExit(f"--eval: {e}") from None
    skill = args.skill or config.skill
    trial = config.trial_config()
    base = config.skill_constants if args.skill is None else args.skill
    trial = trial.replace(search=search_config(base, args.search),
                          time_limit_s=args.time_limit or trial.time_limit_s)  # fmt: skip
    parts, ranges = [], []
    for index in range(len(config.ranges)):
        specs, start = range_specs(config, index), 0
        for count in config.shape_counts():
            take = min(args.per_shape, count)
            parts.append(specs.take(np.arange(start, start + take)))
            ranges += [index] * take
            start += count
    specs, ranges = TrialSpec.concat(parts), np.array(ranges)
    _, controller = load_controller(args.policy)
    start = time.perf_counter()
    result = run_trials(specs, controller(specs), engine="mujoco", config=trial,
                        threads=args.threads)  # fmt: skip
    wall = time.perf_counter() - start
    linear, angular = zip(*config.ranges, strict=True)
    ok, quarter = result.success, quarter_labels(linear, angular)[ranges]  # eval.py's quarters
    cells = []
    for name in QUARTERS:
        inside = quarter == name
        times = [result.time_s[(ranges == r) & ok].mean() for r in np.unique(ranges[inside])
                 if ((ranges == r) & ok).any()]  # fmt: skip
        mean = f"{np.mean(times):4.2f} s" if times else "- s"
        cells.append(f"{name} {ok[inside].mean() * 100:5.1f} % {mean}")
    changes = args.search or "(its constants)"
    print(f"{args.policy}, skill {skill} {changes}, {len(specs)} trials of {args.eval}: "
          + " | ".join(cells))  # fmt: skip
    peak = np.percentile(result.peak_force, [50, 99])
    print(f"all {ok.mean() * 100:.1f} %, protective stops {int(result.protective_stop.sum())}, "
          f"sensed peak median {peak[0]:.0f} N, p99 {peak[1]:.0f} N, "
          f"chatter under 5 N {(result.chatter < 5).mean() * 100:.1f} %, failures with chatter "
          f">= 5 N {int(((result.chatter >= 5) & ~ok).sum())}, {result.steps.mean():,.0f} steps "
          f"per trial, wall {wall:.0f} s")  # fmt: skip
    if args.npz:
        np.savez(args.npz, success=ok, time_s=result.time_s, range=ranges,
                 protective_stop=result.protective_stop, peak_force=result.peak_force)  # fmt: skip


if __name__ == "__main__":
    main()
