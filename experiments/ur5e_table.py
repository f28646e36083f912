"""The paper's real-UR5e table (section 7) in simulation: its 17 cells through the robot runtime.

    python experiments/ur5e_table.py [--policy paper] [--policy-for triangle=transfer]
        [--trials 100] [--skill-constant NAME=VALUE] [--out docs/results/ur5e_table]

Each cell (a peg, its size, a linear error range at 12 deg) runs `python -m mjx_peg.robot` on
the simulated arm as the paper ran the real one: effort commands at 125 Hz over the 500 Hz
physics, a 5 ms actuator lag, the policy's numbers for each trial's estimated hole, `--trials`
trials (the paper: 10), `--skill-constant` (repeatable) set in each policy's skill. A cell
already run (its runs.csv holds every trial, its skill.json the skill asked for) is kept, so a
killed run resumes; a cell of another skill is refused. `--jobs` cells run at once (default:
the cores this process may use; each cell's trials run one after another on one core, and every
cell's result is the same whatever the jobs). Then OUT/table.md and OUT/table.csv:
per cell our successes, the rate with its 95 % Wilson interval, protective stops, the median
time, and the paper's x / 10 beside it, with the one-sided p that our rate is below the paper's
real-robot rate: Fisher's exact test on the two counts, which carries the paper's own 10 trials'
uncertainty (a binomial test against x / 10 as if exact would call any miss below a 10 / 10 cell
significant).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from scipy.stats import fisher_exact

from mjx_peg.cores import cores
from mjx_peg.skill.skill_cli import skill_constant

ROOT = Path(__file__).resolve().parents[1]
# (shape, size mm, linear mm, the paper's successes of 10): the paper's Table 7, angular 12 deg
CELLS = (
    ("circle", 50, 6, 10), ("circle", 50, 8, 10), ("circle", 50, 10, 8),
    ("square", 50, 6, 10), ("square", 50, 8, 9), ("square", 50, 10, 9),
    ("triangle", 50, 6, 10), ("triangle", 50, 8, 7), ("triangle", 50, 10, 5),
    ("circle", 25, 3, 10), ("circle", 25, 4, 10), ("circle", 25, 6, 10),
    ("square", 25, 3, 10), ("square", 25, 4, 10), ("square", 25, 6, 9),
    ("triangle", 25, 3, 10), ("triangle", 25, 4, 8),
)  # fmt: skip
ANGULAR_DEG = 12.0
COMMAND_HZ, LAG_MS = 125.0, 5.0


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The 95 % Wilson score interval of k successes in n; it holds k / n, which rounding would
    put a hair outside at 0 or n successes."""
    if n == 0:
        return math.nan, math.nan
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return min(centre - half, p), max(centre + half, p)


def cell_name(shape: str, size: int, linear: int) -> str:
    return f"{shape}_{size}mm_{linear}mm"


def cell_seed(seed: int, k: int) -> int:
    """The robot CLI's --seed of the table's cell `k` (its index in CELLS) under the table's
    --seed: each cell draws trials of its own."""
    return seed + k


def read_runs(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def cell_skill(policy: str, changes: tuple) -> dict:
    """The skill record a cell of `policy` runs (`NamedSkill.record`), with `changes` ((name,
    value) pairs) to its constants."""
    from mjx_peg.policy.export import choose_skill, load_policy
    from mjx_peg.policy.shipped import resolve_policy

    resolved = resolve_policy(policy)
    loaded = resolved if resolved == "baseline" else load_policy(resolved)
    return choose_skill(None, loaded, changes).record()


def ran_skill(out: Path) -> dict | None:
    """The skill record a cell's skill.json holds, constants added since read as their
    defaults; None where it has none."""
    from mjx_peg.skill.search import record_as_today

    path = out / "skill.json"
    if not path.is_file():
        return None
    record = json.loads(path.read_text())
    return {**record, "constants": record_as_today(record["constants"])}


def run_cell(policy: str, shape: str, size: int, linear: int, trials: int, out: Path,
             seed: int, changes: tuple = ()) -> list[dict]:  # fmt: skip
    """The cell's runs.csv rows, running the robot CLI unless they are all there."""
    runs = out / "runs.csv"
    if runs.is_file() and len(read_runs(runs)) == trials:
        if ran_skill(out) not in (None, cell_skill(policy, changes)):
            raise SystemExit(f"{out} holds a cell of another skill: give another --out")
        return read_runs(runs)
    constants = [a for name, value in changes for a in ("--skill-constant", f"{name}={value}")]
    argv = [sys.executable, "-m", "mjx_peg.robot", "--policy", policy, "--shape", shape,
            "--size", str(size), "--linear-mm", str(linear), "--angular-deg", str(ANGULAR_DEG),
            "--trials", str(trials), "--command-hz", str(COMMAND_HZ), "--actuator-lag-ms",
            str(LAG_MS), "--time-limit", "60", "--seed", str(seed), "--out", str(out),
            "--no-progress", "--force", *constants]  # fmt: skip
    done = subprocess.run(argv, cwd=ROOT, text=True, capture_output=True)
    if done.returncode != 0:
        raise SystemExit(f"{shape} {size} mm {linear} mm: {done.stderr.strip()}")
    print(done.stdout.strip(), flush=True)
    return read_runs(runs)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", default="paper", help="the policy of every cell (default paper)")
    p.add_argument("--policy-for", action="append", default=[], metavar="SHAPE=POLICY",
                   help="another policy for one shape, e.g. triangle=transfer")  # fmt: skip
    p.add_argument("--trials", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("docs/results/ur5e_table"))
    p.add_argument("--jobs", type=int, default=cores(),
                   help="cells run at once (default: the cores this process may use)")  # fmt: skip
    p.add_argument(
        "--skill-constant",
        action="append",
        default=[],
        type=skill_constant,
        metavar="NAME=VALUE",
        help="a constant of every cell's skill set (repeatable)",
    )
    args = p.parse_args(argv)
    if args.jobs < 1:
        raise SystemExit(f"--jobs must be at least 1, got {args.jobs}")
    changes = tuple(args.skill_constant)
    policies = {}
    for item in args.policy_for:
        shape, _, policy = item.partition("=")
        if not policy:
            raise SystemExit(f"--policy-for takes SHAPE=POLICY, got {item!r}")
        policies[shape] = policy
    cell_policies = [policies.get(shape, args.policy) for shape, *_ in CELLS]

    def cell(k: int) -> list[dict]:
        shape, size, linear, _ = CELLS[k]
        out = args.out / cell_name(shape, size, linear)
        return run_cell(cell_policies[k], shape, size, linear, args.trials, out,
                        cell_seed(args.seed, k), changes)  # fmt: skip

    with ThreadPoolExecutor(max_workers=args.jobs) as pool:  # each waits on its subprocess
        ran = list(pool.map(cell, range(len(CELLS))))
    rows = []
    for (shape, size, linear, paper), policy, runs in zip(CELLS, cell_policies, ran, strict=True):
        ok = np.array([int(r["success"]) for r in runs], bool)
        times = np.array([float(r["time_s"]) for r in runs])[ok]
        stops = sum(int(r["protective_stop"]) for r in runs)
        lo, hi = wilson(int(ok.sum()), ok.size)
        # one-sided: our rate below the paper's real-robot rate (p small: it is below)
        counts = [[int(ok.sum()), int((~ok).sum())], [paper, 10 - paper]]
        below = float(fisher_exact(counts, alternative="less").pvalue)
        rows.append(dict(shape=shape, size_mm=size, linear_mm=linear, angular_deg=ANGULAR_DEG,
                         policy=policy, trials=ok.size, successes=int(ok.sum()),
                         rate=ok.mean(), wilson_low=lo, wilson_high=hi, protective_stops=stops,
                         median_time_s=float(np.median(times)) if times.size else math.nan,
                         paper_successes=paper, paper_trials=10, p_below_paper=below))  # fmt: skip
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "table.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    lines = [
        f"The paper's UR5e table in simulation: the robot runtime on the simulated arm, "
        f"{COMMAND_HZ:g} Hz commands, {LAG_MS:g} ms actuator lag, {args.trials} trials per cell, "
        f"+-{ANGULAR_DEG:g} deg (`python experiments/ur5e_table.py`"
        + "".join(f" --skill-constant {n}={v:g}" for n, v in changes)
        + ").",
        "",
        "| peg | linear | policy | ours | 95 % interval | protective stops | median time | "
        "the paper (real UR5e) | p (ours below the paper, Fisher) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['shape']} {r['size_mm']} mm | {r['linear_mm']} mm | {r['policy']} | "
            f"{r['successes']} / {r['trials']} ({100 * r['rate']:.0f} %) | "
            f"{100 * r['wilson_low']:.0f}-{100 * r['wilson_high']:.0f} % | "
            f"{r['protective_stops']} | {r['median_time_s']:.2f} s | {r['paper_successes']} / 10 | "
            f"{r['p_below_paper']:.2g} |"
        )
    at_or_above = sum(r["rate"] >= r["paper_successes"] / 10 for r in rows)
    lines += ["", f"At or above the paper's real-robot rate: {at_or_above} of {len(rows)} cells."]
    (args.out / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
