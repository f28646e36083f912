"""Where a protective stop on the simulated arm comes from: trials of the paper's UR5e table
replayed through the robot runtime at the table's command rate and actuator lag, without the lag,
and at the engines' 500 Hz, each policy's peak sensed force over the trial's first seconds.

    python experiments/arm_touchdown.py --stops docs/results/ur5e_table [--policy family
        --policy paper] [--seconds 2] [--within 1.2]
    python experiments/arm_touchdown.py --cell circle_50mm_6mm --trial 20 [--trial 21 ...]
        [--skill-constant NAME=VALUE]

`--stops DIR` replays every trial of a UR5e table's folder (`experiments/ur5e_table.py --out
DIR`: its CELL/runs.csv) that ended in a protective stop within `--within` seconds; `--cell` and
`--trial` name trials instead. A cell's trials are the table's (`sample_trials` of its task with
the cell's seed, `ur5e_table.cell_seed`), so a trial here is the table's trial. Each line: the
trial, the policy, and for each of 125 Hz with the 5 ms lag, 125 Hz without it and 500 Hz
without it, the largest sensed tool force (the protective stop's reading,
`SkillRuntime.peak_force`) over `--seconds`, and STOP where it passed the 150 N limit.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ur5e_table import ANGULAR_DEG, CELLS, COMMAND_HZ, LAG_MS, cell_name, cell_seed, read_runs

from mjx_peg.engines.trial import TrialConfig
from mjx_peg.policy.export import choose_skill, load_policy
from mjx_peg.policy.shipped import resolve_policy
from mjx_peg.robot import runtime, sim_arm
from mjx_peg.robot.cli import command_steps
from mjx_peg.skill.skill_cli import skill_constant
from mjx_peg.world.task import TaskConfig, sample_trials

# (command rate Hz, actuator lag ms): the table's, the table's without its lag, the engines'
RATES = ((COMMAND_HZ, LAG_MS), (COMMAND_HZ, 0.0), (500.0, 0.0))
CELL_NAMES = [cell_name(shape, size, linear) for shape, size, linear, _ in CELLS]


def early_stops(folder: Path, within: float) -> list[tuple[str, int, int]]:
    """(cell, trial, the cell's trials) of every protective stop within `within` s in a UR5e
    table's folder."""
    found = []
    for name in CELL_NAMES:
        runs = folder / name / "runs.csv"
        if runs.is_file():
            rows = read_runs(runs)
            found += [(name, int(r["trial"]), len(rows)) for r in rows
                      if r["protective_stop"] == "1" and float(r["time_s"]) <= within]  # fmt: skip
    return found


def replay(policy, cell: str, trial: int, trials: int, seconds: float, seed: int = 0,
           changes: tuple = ()) -> list:  # fmt: skip
    """[(peak sensed force N, stopped)] of `trial` of the `trials` of `cell` (the table's draw
    depends on their number) at each of RATES, `changes` ((name, value) pairs) set in the
    policy's skill."""
    k = CELL_NAMES.index(cell)
    shape, size, linear, _ = CELLS[k]
    task = TaskConfig.from_mm_deg((shape,), size, linear, ANGULAR_DEG)
    specs = sample_trials(task, cell_seed(seed, k), trials)
    skill = choose_skill(None, policy, changes)
    config = TrialConfig(time_limit_s=60.0, search=skill.config)
    hole = runtime.HoleEstimate.of_trial(specs, trial)
    vector = runtime.controller_vector(policy, hole)
    out = []
    for hz, lag_ms in RATES:
        arm = sim_arm.SimArm(specs, trial, command_steps=command_steps(hz, 60.0),
                             success_height=config.success_height,
                             actuator_lag_s=lag_ms / 1000.0)  # fmt: skip
        run = runtime.run_skill(arm, runtime.SkillRuntime(vector, hole, config),
                                time_limit_s=seconds, done=arm.inserted)  # fmt: skip
        out.append((run.peak_force, run.protective_stop))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--stops", type=Path, help="a UR5e table's folder: replay its early stops")
    p.add_argument("--within", type=float, default=1.2, help="s: an early stop's end (1.2)")
    p.add_argument("--cell", help="a cell's name, e.g. circle_50mm_6mm (with --trial)")
    p.add_argument("--trial", type=int, action="append", default=[], help="repeatable")
    p.add_argument("--policy", action="append", default=[], help="repeatable (family, paper)")
    p.add_argument("--seconds", type=float, default=2.0, help="of each trial (default 2)")
    p.add_argument("--seed", type=int, default=0, help="the table's --seed (default 0)")
    p.add_argument("--table-trials", type=int, default=100,
                   help="with --cell: the table's --trials (default 100)")  # fmt: skip
    p.add_argument("--skill-constant", action="append", default=[], type=skill_constant,
                   metavar="NAME=VALUE", help="in every policy's skill (repeatable)")  # fmt: skip
    args = p.parse_args(argv)
    if (args.stops is None) == (args.cell is None):
        raise SystemExit("give --stops DIR or --cell NAME --trial K")
    if args.cell is not None and not args.trial:
        raise SystemExit("--cell needs --trial K (repeatable)")
    if args.cell is not None and args.cell not in CELL_NAMES:
        raise SystemExit(f"--cell: {args.cell!r} is none of the table's cells: "
                         f"{', '.join(CELL_NAMES)}")  # fmt: skip
    outside = [k for k in args.trial if not 0 <= k < args.table_trials]
    if outside:
        raise SystemExit(f"--trial must lie in 0..{args.table_trials - 1}, got {outside}")
    if not args.seconds > 0:
        raise SystemExit(f"--seconds must be a positive number, got {args.seconds}")
    if args.stops is not None:
        if not args.stops.is_dir():
            raise SystemExit(f"--stops: no folder {args.stops}")
        chosen = early_stops(args.stops, args.within)
        print(f"{len(chosen)} protective stops within {args.within:g} s in {args.stops}")
    else:
        chosen = [(args.cell, k, args.table_trials) for k in args.trial]
    policies = {name: load_policy(resolve_policy(name, baseline=False))
                for name in args.policy or ["family", "paper"]}  # fmt: skip
    heads = [f"{hz:g} Hz, {lag:g} ms lag" for hz, lag in RATES]
    print(f"| cell | trial | policy | {' | '.join(heads)} |")
    print("|---|---:|---|" + "---:|" * len(RATES))
    for cell, trial, trials in chosen:
        for name, policy in policies.items():
            peaks = replay(policy, cell, trial, trials, args.seconds, args.seed,
                           tuple(args.skill_constant))  # fmt: skip
            text = [f"{peak:.0f} N{' STOP' if stop else ''}" for peak, stop in peaks]
            print(f"| {cell} | {trial} | {name} | {' | '.join(text)} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
