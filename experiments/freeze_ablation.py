"""What each learned constant of the skill is worth: a policy's numbers with one constant frozen
at its hand-tuned value in turn, on the same trials, paired against the policy as learned.

    python experiments/freeze_ablation.py --policy runs/paper/seed-0 [--trials 1500]
        [--linear-mm 8] [--angular-deg 12] [--seed 2] [--time-limit 60] [--only spiral_pitch,k]
        [--csv FILE]

The policy's 47 numbers per trial (the controller's 38 and the contact search's 9,
`skill.params.LEARNED_NAMES`); frozen in turn: each of the 9, the two stiffnesses together
("k"), the compliance's diagonal ("C diagonal") and its couplings ("C couplings"), each at the
policy's hand-tuned start (the baseline's 38 and the skill's constants,
`TrainConfig.prior_vector`). One markdown row per variant: success, the change against the
policy (points), trials lost / gained and the exact McNemar p; `--csv` writes the same rows.
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from scipy.stats import binomtest

from mjx_peg.engines import run_trials
from mjx_peg.learn.config import TrainConfig
from mjx_peg.policy.export import load_policy
from mjx_peg.skill.params import LEARNED_NAMES, N_PARAMS
from mjx_peg.world.task import TaskConfig, sample_trials

DIAGONAL = [2 + 7 * i for i in range(6)]
GROUPS = {
    "k": [0, 1],
    "C diagonal": DIAGONAL,
    "C couplings": [i for i in range(2, N_PARAMS) if i not in DIAGONAL],
}


def variants(names: list[str] | None) -> dict[str, list[int]]:
    """{variant: the columns it freezes}: the search's 9 one by one, then the groups."""
    out = {name: [LEARNED_NAMES.index(name)] for name in LEARNED_NAMES[N_PARAMS:]}
    out.update(GROUPS)
    if names:
        unknown = set(names) - set(out)
        if unknown:
            raise SystemExit(f"--only: unknown {sorted(unknown)}; choose from {', '.join(out)}")
        out = {k: v for k, v in out.items() if k in names}
    return out


def paired(base: np.ndarray, other: np.ndarray) -> tuple[int, int, float]:
    """Trials lost and gained against `base`, and the exact McNemar p."""
    lost, gained = int(np.sum(base & ~other)), int(np.sum(~base & other))
    p = binomtest(lost, lost + gained).pvalue if lost + gained else 1.0
    return lost, gained, float(p)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", required=True, help="a policy that learned the skill's constants")
    p.add_argument("--trials", type=int, default=1500)
    p.add_argument("--linear-mm", type=float, default=8.0)
    p.add_argument("--angular-deg", type=float, default=12.0)
    p.add_argument("--seed", type=int, default=2)
    p.add_argument("--time-limit", type=float, default=60.0, help="per trial (default 60 s)")
    p.add_argument("--shapes", default="circle,square")
    p.add_argument("--only", help="comma-separated variants (default: every one)")
    p.add_argument("--csv", help="write the rows here too")
    args = p.parse_args(argv)
    policy = load_policy(args.policy)
    config = TrainConfig.from_json(policy.manifest["config"])
    if not config.learns_search:
        raise SystemExit(f"{args.policy} did not learn the skill's constants")
    task = TaskConfig(shapes=tuple(args.shapes.split(",")), linear_error=args.linear_mm / 1000,
                      angular_error=math.radians(args.angular_deg))  # fmt: skip
    specs = sample_trials(task, args.seed, args.trials)
    learned = policy.controller_vectors(specs)
    prior = config.prior_vector()
    trial = config.trial().replace(time_limit_s=args.time_limit)
    base = run_trials(specs, learned, config=trial).success
    rows = [("as learned", base.mean(), 0.0, 0, 0, 1.0)]
    print(f"{args.policy}: {len(specs)} trials, as learned {100 * base.mean():.1f} %", flush=True)
    for name, columns in variants(args.only and args.only.split(",")).items():
        frozen = learned.copy()
        frozen[:, columns] = prior[columns]
        success = run_trials(specs, frozen, config=trial).success
        lost, gained, pvalue = paired(base, success)
        rows.append((name, success.mean(), success.mean() - base.mean(), lost, gained, pvalue))
        print(f"{name}: {100 * success.mean():.1f} % ({lost} lost, {gained} gained, p = "
              f"{pvalue:.2g})", flush=True)  # fmt: skip
    lines = ["| frozen at the hand-tuned value | success | against as learned | lost / gained, "
             "McNemar p |", "|---|---|---|---|"]  # fmt: skip
    for name, rate, delta, lost, gained, pvalue in rows:
        change = "" if name == "as learned" else f"{100 * delta:+.1f}"
        pair = "" if name == "as learned" else f"{lost} / {gained}, p = {pvalue:.2g}"
        lines.append(f"| {name} | {100 * rate:.1f} % | {change} | {pair} |")
    print("\n".join(lines))
    if args.csv:
        with open(args.csv, "w") as f:
            f.write("variant,success_rate,change,lost,gained,mcnemar_p\n")
            for row in rows:
                f.write(",".join(str(v) for v in row) + "\n")


if __name__ == "__main__":
    main()
