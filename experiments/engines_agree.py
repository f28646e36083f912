"""Sim-to-sim check: the same specs and parameters on the mujoco and mjx engines.

    python experiments/engines_agree.py [--trials 100] [--time-limit 4] [--batch 25]
        [--skill spiral|paper] [--policy paper|baseline|quick|...] [--out F.npz]

Prints the fraction of trials with the same outcome (of all, and of those that ended within the
time limit on the mujoco engine), the median times to complete of the trials both engines
completed, and the final tip distance between the engines. For scale it also runs the mujoco
engine on the same specs with every hole moved by --nudge-m (default 1e-9 m): how often that
alone flips an outcome. --skill and --policy: the skill and the controller's numbers (a
policy's vectors for each trial, or the hand-tuned baseline); by default the shipped ones, the
spiral and `paper`. --out saves both engines' per-trial results (.npz).
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.policy.export import load_policy
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.search import SKILLS, skill_config
from mjx_peg.world.task import TaskConfig, TrialSpec, sample_trials


def agreement_specs(
    trials: int = 100,
    shapes: tuple[str, ...] = ("circle", "square", "triangle"),
    linear_mm: float = 3.0,
    angular_deg: float = 4.0,
    seed: int = 11,
) -> TrialSpec:
    """The specs both engines run (this script's defaults; contact_diff.py reuses them)."""
    task = TaskConfig(
        shapes=shapes, linear_error=linear_mm / 1000.0, angular_error=np.deg2rad(angular_deg)
    )
    return sample_trials(task, seed, trials)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=100)
    p.add_argument("--time-limit", type=float, default=4.0, help="simulated s per trial")
    p.add_argument("--batch", type=int, default=25, help="mjx slots")
    p.add_argument("--shapes", default="circle,square,triangle")
    p.add_argument("--linear-mm", type=float, default=3.0)
    p.add_argument("--angular-deg", type=float, default=4.0)
    p.add_argument("--seed", type=int, default=11)
    p.add_argument("--nudge-m", type=float, default=1e-9, help="hole shift of the C-vs-C check")
    p.add_argument("--skill", default="spiral", choices=tuple(SKILLS))
    p.add_argument("--policy", default="paper", help="'baseline', a shipped policy or a run")
    p.add_argument("--out", help="save per-trial results of both engines to this .npz")
    args = p.parse_args(argv)
    specs = agreement_specs(
        args.trials, tuple(args.shapes.split(",")), args.linear_mm, args.angular_deg, args.seed
    )
    params = baseline_params()
    if args.policy != "baseline":
        params = load_policy(args.policy).controller_vectors(specs)
    config = TrialConfig(time_limit_s=args.time_limit, search=skill_config(args.skill))
    start = time.perf_counter()
    cpu = run_trials(specs, params, engine="mujoco", config=config)
    cpu_s = time.perf_counter() - start
    start = time.perf_counter()
    acc = run_trials(specs, params, engine="mjx", config=config, batch=args.batch)
    acc_s = time.perf_counter() - start
    rng = np.random.default_rng(args.seed)
    nudge = args.nudge_m * rng.standard_normal(specs.board_pos.shape)
    nudged = run_trials(
        dataclasses.replace(specs, board_pos=specs.board_pos + nudge),
        params, engine="mujoco", config=config,
    )  # fmt: skip
    same = cpu.success == acc.success
    ended = cpu.steps < config.max_steps  # ended within the limit on the mujoco engine
    both = cpu.success & acc.success
    t_cpu, t_acc = np.median(cpu.time_s[both]), np.median(acc.time_s[both])
    tip_gap = np.linalg.norm(cpu.final_tip_pos - acc.final_tip_pos, axis=1)
    print(f"mujoco: {cpu.summary()} ({cpu_s:.0f} s wall)")
    print(f"mjx:    {acc.summary()} ({acc_s:.0f} s wall incl. compile)")
    print(f"same outcome on {same.sum()}/{len(specs)} = {100 * same.mean():.1f} %; of the "
          f"{ended.sum()} that ended within the limit on mujoco: {same[ended].sum()}")  # fmt: skip
    print(
        f"median time, both succeeded ({both.sum()}): mujoco {t_cpu:.3f} s, mjx {t_acc:.3f} s "
        f"({100 * (t_acc / t_cpu - 1):+.1f} %)"
    )
    print(f"final tip distance between engines: median {1000 * np.median(tip_gap):.2f} mm")
    per_shape = {}
    for sid in np.unique(specs.shape_id):
        rows = specs.shape_id == sid
        per_shape[int(sid)] = f"{same[rows].sum()}/{rows.sum()}"
    print("same outcome per shape id:", per_shape)
    flips = np.flatnonzero(~same)
    print("trials with different outcomes:", flips.tolist())
    floor = nudged.success == cpu.success
    print(
        f"mujoco vs mujoco with holes moved by {args.nudge_m:g} m: same outcome on "
        f"{floor.sum()}/{len(specs)} = {100 * floor.mean():.1f} %; of those that ended: "
        f"{floor[ended].sum()}/{ended.sum()}"
    )
    if args.out:
        arrays = {f"mujoco_{k}": v for k, v in cpu.to_arrays().items()}
        arrays |= {f"mjx_{k}": v for k, v in acc.to_arrays().items()}
        arrays["nudged_success"] = nudged.success  # C MuJoCo, every hole moved by --nudge-m
        np.savez(args.out, **arrays, **{f"spec_{k}": v for k, v in specs.to_arrays().items()})
        print(f"per-trial results: {args.out}")


if __name__ == "__main__":
    main()
