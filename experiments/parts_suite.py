"""The parts suite: a family of parts beyond the paper's, each with its errors scaled to its size.

    python experiments/parts_suite.py --policy baseline --policy paper [--policy NAME=RUN_DIR]
        [--trials 300] [--first N] [--seed 0] [--part-scale absolute|size]
        [--skill-constant NAME=VALUE] [--only PART,...] [--out docs/results/parts]

The suite (`world/family.py` SUITE) spans the five shapes, sizes 10-80 mm and both clearance
classes (the paper's fits and tight ones, `world/parts.py`); its held-out parts are in no
training run (the `family` preset trains on the others). Every part runs `--trials` trials of
its own (drawn from the seed and the part's name, so adding a part changes no other's trials)
at the paper's middle errors scaled as its preset grids scale them: +-4 mm x S / 50 mm of
localization and grasp height, +-6 deg of yaw and tilt (an angle is the same error for a part of
any size), 60 s, on the C engine. A policy is 'baseline' (the hand-tuned numbers), a shipped
policy's name or a run directory, each run with the skill its manifest names (the baseline: the
shipped skill, the spiral); `--part-scale size` runs the spiral's lengths scaled with the part
instead (`SkillConfig.part_scale`).

One CSV per policy and part under OUT/POLICY/ (a row per trial: outcome, time, protective stop,
chatter, failure class), so a killed run resumes part by part; then OUT/parts.csv and
OUT/parts.md (per policy and part: success with its 95 % Wilson interval, the time to insert p50
/ p90, protective stops, failures with chatter >= 5 N among the trials over 1.2 s
(`engines.trial.chattering`), the failure taxonomy of
`evaluation/taxonomy.py`) and OUT/parts.png. `--first N` runs only the first N of each part's
`--trials` trials, the same trials as the whole suite's: a screen whose trials pair with it.
"""

from __future__ import annotations

import argparse
import csv
import functools
import json
import math
import sys
import zlib
from pathlib import Path

import numpy as np
from ur5e_table import wilson  # experiments/ur5e_table.py

from mjx_peg import outdir
from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import CHATTER_LIMIT_N, CHATTER_MIN_TIME_S, TrialConfig, chattering
from mjx_peg.evaluation import taxonomy
from mjx_peg.evaluation.runner import load_controller
from mjx_peg.policy.export import load_policy
from mjx_peg.policy.shipped import resolve_policy
from mjx_peg.skill.search import (
    PART_SCALES,
    constants_record,
    named_skill,
    record_as_today,
)
from mjx_peg.skill.skill_cli import skill_constant
from mjx_peg.world.family import SUITE, Part
from mjx_peg.world.task import TaskConfig, sample_trials

LINEAR_MM_AT_50, ANGULAR_DEG = 4.0, 6.0  # the paper's middle errors at its 50 mm parts
FIELDS = ("trial", "success", "time_s", "protective_stop", "chatter_n", "peak_force_n", "failure")


def part_task(part: Part) -> TaskConfig:
    """The part's trials: its shape, size and fit, errors scaled with its size."""
    return TaskConfig.from_mm_deg(
        (part.shape,),
        (part.size_mm,),
        LINEAR_MM_AT_50 * part.size_mm / 50.0,
        ANGULAR_DEG,
        hole_scale=part.hole_scale,
    )


def part_seed(seed: int, part: Part) -> int:
    return (seed + zlib.crc32(part.name.encode())) % 2**32


# A policy is read once per run, not once per part
controller_of = functools.cache(lambda policy: load_controller(policy)[1])
policy_of = functools.cache(load_policy)


def policy_skill(policy: str, part_scale: str | None, changes=()):
    """The skill a policy runs in the suite: its manifest's (the baseline: the spiral), with
    `changes` ((name, value) pairs of `--skill-constant`) to its constants."""
    skill = named_skill("spiral") if policy == "baseline" else policy_of(policy).skill
    config = skill.config
    if part_scale is not None:
        config = config.replace(part_scale=part_scale)
    return config.replace(**dict(changes))


def read_rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def run_part(policy: str, part: Part, args, out: Path, progress=None) -> list[dict]:
    """The part's rows, running its trials unless its CSV already holds them all."""
    trials = args.first or args.trials
    if out.is_file():
        rows = read_rows(out)
        if len(rows) == trials:
            return rows
    specs = sample_trials(part_task(part), part_seed(args.seed, part), args.trials)
    specs = specs.take(np.arange(trials))  # --first: the suite's first trials, as drawn there
    controller = controller_of(policy)
    search = policy_skill(policy, args.part_scale, args.skill_constant)
    config = TrialConfig(time_limit_s=args.time_limit, search=search)
    result = run_trials(specs, controller(specs), engine="mujoco", config=config,
                        progress=progress)  # fmt: skip
    arrays = result.to_arrays()
    label = taxonomy.classify(specs, arrays)
    rows = [
        dict(trial=k, success=int(arrays["success"][k]), time_s=f"{arrays['time_s'][k]:.3f}",
             protective_stop=int(arrays["protective_stop"][k]),
             chatter_n=f"{arrays['chatter'][k]:.3f}", peak_force_n=f"{arrays['peak_force'][k]:.2f}",
             failure="" if label[k] < 0 else taxonomy.CLASSES[label[k]])
        for k in range(trials)
    ]  # fmt: skip

    def write(path: Path) -> None:
        with open(path, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=FIELDS)
            writer.writeheader()
            writer.writerows(rows)

    outdir.write_atomic(out, write)
    return [{k: str(v) for k, v in r.items()} for r in rows]


def check_folder(folder: Path, given: str, policy: str, args) -> None:
    """OUT/LABEL/suite.json records what its CSVs ran (the policy as the command named it);
    another policy, skill or set of trials there is refused rather than mixed in."""
    record = dict(policy=given, skill=constants_record(policy_skill(policy, args.part_scale,
                                                       args.skill_constant)),
                  trials=args.trials, seed=args.seed, linear_mm_at_50=LINEAR_MM_AT_50,
                  angular_deg=ANGULAR_DEG, time_limit_s=args.time_limit,
                  **({"first": args.first} if args.first else {}))  # fmt: skip
    path = folder / "suite.json"
    if path.is_file():
        saved = json.loads(path.read_text())
        if isinstance(saved.get("skill"), dict):  # constants added since: their defaults, off
            saved["skill"] = record_as_today(saved["skill"])
        if saved != json.loads(json.dumps(record)):
            differ = sorted(k for k in record if saved.get(k) != json.loads(json.dumps(record[k])))
            raise SystemExit(
                f"{folder} holds the suite of another run (its {' and '.join(differ)} "
                f"{'differ' if len(differ) > 1 else 'differs'}): give another label "
                "(--policy LABEL=POLICY) or --out"
            )
        return
    folder.mkdir(parents=True, exist_ok=True)
    outdir.write_json(path, record)


def summary(policy: str, part: Part, rows: list[dict]) -> dict:
    ok = np.array([r["success"] == "1" for r in rows])
    duration = np.array([float(r["time_s"]) for r in rows])
    times = duration[ok]
    chatter = np.array([float(r["chatter_n"]) for r in rows])
    lo, hi = wilson(int(ok.sum()), ok.size)
    p50, p90 = np.percentile(times, [50, 90]) if times.size else (math.nan, math.nan)
    counts = {c: sum(r["failure"] == c for r in rows) for c in taxonomy.CLASSES}
    return dict(
        policy=policy, part=part.name, shape=part.shape, size_mm=part.size_mm, fit=part.fit,
        held_out=int(part.held_out), trials=ok.size, successes=int(ok.sum()),
        success_pct=100 * ok.mean(), wilson_low_pct=100 * lo, wilson_high_pct=100 * hi,
        time_p50_s=p50, time_p90_s=p90,
        protective_stops=sum(r["protective_stop"] == "1" for r in rows),
        chatter_failures=int(np.sum(~ok & chattering(chatter, duration))),
        **{c.replace(" ", "_"): n for c, n in counts.items()},
    )  # fmt: skip


def markdown(table: list[dict], trials: str, seed: int, time_limit: float) -> str:
    lines = [
        f"The parts suite (`python experiments/parts_suite.py`): {trials} per part, seed "
        f"{seed}, +-{LINEAR_MM_AT_50:g} mm x S / 50 mm, +-{ANGULAR_DEG:g} deg, {time_limit:g} s. "
        f"Held out of all training: {', '.join(p.name for p in SUITE if p.held_out)}.",
        "",
        "| part | policy | success | 95 % interval | time p50 / p90 | protective stops | "
        f"failures chattering >= {CHATTER_LIMIT_N:g} N (over {CHATTER_MIN_TIME_S:g} s) | "
        "failures by class |",
        "|---|---|---:|---|---|---:|---:|---|",
    ]
    for r in table:
        failures = ", ".join(
            f"{c} {r[c.replace(' ', '_')]}" for c in taxonomy.CLASSES if r[c.replace(" ", "_")]
        )
        lines.append(
            f"| {r['part']}{' (held out)' if r['held_out'] else ''} | {r['policy']} | "
            f"{r['success_pct']:.1f} % | {r['wilson_low_pct']:.0f}-{r['wilson_high_pct']:.0f} % | "
            f"{r['time_p50_s']:.2f} / {r['time_p90_s']:.2f} s | {r['protective_stops']} | "
            f"{r['chatter_failures']} | {failures or '-'} |"
        )
    return "\n".join(lines) + "\n"


def plot(table: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    policies = list(dict.fromkeys(r["policy"] for r in table))
    parts = list(dict.fromkeys(r["part"] for r in table))
    width = 0.8 / len(policies)
    fig, ax = plt.subplots(figsize=(max(8, 0.7 * len(parts) * len(policies) ** 0.5), 4.2))
    x = np.arange(len(parts))
    for k, policy in enumerate(policies):
        rows = {r["part"]: r for r in table if r["policy"] == policy}
        rate = np.array([rows[p]["success_pct"] if p in rows else np.nan for p in parts])
        err = np.array([[rows[p]["success_pct"] - rows[p]["wilson_low_pct"],
                         rows[p]["wilson_high_pct"] - rows[p]["success_pct"]]
                        if p in rows else [np.nan, np.nan] for p in parts]).T  # fmt: skip
        ax.bar(x + (k - (len(policies) - 1) / 2) * width, rate, width, yerr=err, capsize=2,
               label=policy)  # fmt: skip
    held = [p in {q.name for q in SUITE if q.held_out} for p in parts]
    ax.set_xticks(x, [p + (" *" if h else "") for p, h in zip(parts, held, strict=True)],
                  rotation=45, ha="right")  # fmt: skip
    ax.axhline(95, color="0.5", lw=0.8, ls="--")
    ax.set_ylim(0, 100)
    ax.set_ylabel("success (%), 95 % interval")
    ax.set_title("The parts suite (* held out of training)")
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    outdir.write_atomic(path, lambda p: fig.savefig(p, dpi=110, format="png"))
    plt.close(fig)


def parse_policy(text: str) -> tuple[str, str, str]:
    """(label, the policy as given, its folder) of 'LABEL=POLICY' or 'POLICY' (labelled by its
    folder's name)."""
    label, _, given = text.rpartition("=")
    if not given:
        raise SystemExit(f"--policy takes POLICY or LABEL=POLICY, got {text!r}")
    policy = given if given == "baseline" else str(resolve_policy(given))
    return label or Path(policy).name, given, policy


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", action="append", default=[], metavar="[LABEL=]POLICY",
                   help="baseline, a shipped policy's name or a run directory; repeat")  # fmt: skip
    p.add_argument("--trials", type=int, default=300, help="trials per part (default 300)")
    p.add_argument(
        "--first",
        type=int,
        default=0,
        metavar="N",
        help="only the first N of each part's trials (a screen; default: all)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--time-limit", type=float, default=60.0, help="per trial (default 60 s)")
    p.add_argument(
        "--part-scale",
        choices=PART_SCALES,
        default=None,
        help="the spiral's lengths absolute or scaled with S (default: the skill's)",
    )
    p.add_argument("--skill-constant", action="append", default=[], type=skill_constant,
                   metavar="NAME=VALUE", help="one of the skill's constants set for every "
                   "policy (repeatable; recorded in OUT/LABEL/suite.json)")  # fmt: skip
    p.add_argument("--only", default="", help="comma-separated part names (default: every one)")
    p.add_argument("--out", type=Path, default=Path("docs/results/parts"))
    args = p.parse_args(argv)
    if not args.policy:
        args.policy = ["baseline", "paper"]
    if args.trials < 1:
        raise SystemExit(f"--trials must be a positive integer, got {args.trials}")
    if not 0 <= args.first <= args.trials:
        raise SystemExit(f"--first must lie in 1..--trials ({args.trials}), got {args.first}")
    names = {part.name: part for part in SUITE}
    chosen = [names[n] for n in args.only.split(",") if n] if args.only else list(SUITE)
    unknown = [n for n in args.only.split(",") if n and n not in names]
    if unknown:
        raise SystemExit(f"--only: unknown parts {unknown}; the suite's: {', '.join(names)}")
    policies = [parse_policy(text) for text in args.policy]
    from tqdm import tqdm

    table = []
    with outdir.exclusive(args.out):
        todo = [(label, policy, part) for label, _, policy in policies for part in chosen]
        for label, given, policy in policies:
            check_folder(args.out / label, given, policy, args)
        per_part = args.first or args.trials
        bar = tqdm(total=len(todo) * per_part, desc="parts suite", unit="trial",
                   smoothing=0.0, dynamic_ncols=True)  # fmt: skip
        with bar:
            for label, policy, part in todo:
                rows = run_part(policy, part, args, args.out / label / f"{part.name}.csv",
                                bar.update)  # fmt: skip
                bar.n = max(bar.n, len(table) * per_part + len(rows))
                table.append(summary(label, part, rows))
                r = table[-1]
                bar.write(f"{label} {part.name}: {r['success_pct']:.1f} % ({r['successes']} / "
                          f"{r['trials']}), stops {r['protective_stops']}")  # fmt: skip
        order = {part.name: k for k, part in enumerate(SUITE)}
        labels = [label for label, _, _ in policies]
        table.sort(key=lambda r: (order[r["part"]], labels.index(r["policy"])))
        with open(args.out / "parts.csv", "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(table[0]))
            writer.writeheader()
            writer.writerows(table)
        trials = f"{args.trials} trials"
        if args.first:
            trials = f"the first {args.first} of {trials}"
        text = markdown(table, trials, args.seed, args.time_limit)
        (args.out / "parts.md").write_text(text)
        plot(table, args.out / "parts.png")
    print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
