"""Regenerate every published number of the shipped skill, one job at a time, niced.

When the trial or the spiral skill changes, every number of it on the results page
(docs/results.md) is rerun: `quick` and `transfer` retrained and re-shipped
(`experiments/ship_policy.py`, at HEAD), the spiral grids under docs/eval/ (`paper-small` at 50
mm, the triangle before and after transfer, 25 and 60 mm, the flange model, the baseline, the
family policy), the 500- and 1,500-trial contact sets, the paper's skill on the 500, zero
error, the sensor and friction variants, the simulated arm, the parts suite, the paper's UR5e
table on the simulated arm (`paper` with `transfer` for the triangles, and `family`), vision to
action, and the nominal 350-range grids last (`paper`, then `family`). `policies/paper` and
`policies/family` are not retrained (`python train.py --preset paper`, ~22 min here, or
`--preset family`, ~31 min, is a decision of its own); each
manifest records again that it runs the spiral skill, with the spiral's constants as they are,
so that `--policy paper` runs it without `--skill`, as the README writes its commands, and the
range of its training parts' features (`ship_policy.record_skill`).

    python experiments/regenerate.py                       # everything, ~255 min on 2 cores
    python experiments/regenerate.py --dry-run             # the commands, nothing run
    python experiments/regenerate.py --only 'g_*,paper46'  # some steps (fnmatch patterns)
    python experiments/regenerate.py --skip-nominal        # all but the 30 min nominal grids
    python experiments/regenerate.py --redo train_quick    # steps done before, run again

A killed run resumes: rerun the same command. Each finished step leaves OUT/NAME.done and is
skipped (`--redo` runs such steps again from their start, their output folder removed first); a
grid is removed before its first start only (a stale grid of the skill before would
otherwise be resumed under the same config), then eval.py resumes it; a training resumes from
its checkpoints. OUT belongs to one commit (OUT/commit): after a new commit, use a new OUT.
Logs go to OUT (default runs/regenerate); the grids to docs/eval/, the contact sets, zero error
and the simulated arm to docs/results/, vision to action to docs/vision/act/. Once every chosen
step is done, experiments/results_page.py writes docs/results.md from them. The steps' durations
are those of the last regeneration on this 2-core CPU, for the ETA.
"""

from __future__ import annotations

import argparse
import dataclasses
import fnmatch
import os
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EVAL = "docs/eval"
RESULTS = "docs/results"  # the other shipped results: contact sets, zero error, the arm


@dataclasses.dataclass(frozen=True)
class Step:
    name: str
    argv: tuple[str, ...]
    expect_s: float  # its wall time in the last regeneration here (the ETA)
    fresh: str = ""  # a path removed before the step's first start


def steps(out: str, commit: str, results: str = RESULTS) -> list[Step]:
    """Every step, in the order they run (the grids the later ones compare with come first);
    `results`: where the contact sets, zero error and the arm's runs go."""
    # fmt: off
    py = sys.executable
    train = [
        Step("train_quick", (py, "train.py", "--no-progress"), 370, "runs/quick"),
        Step("ship_quick", (py, "experiments/ship_policy.py", "runs/quick", "quick", "--commit",
                            commit, "--command", "python train.py"), 5),
        Step("train_transfer", (py, "train.py", "--preset", "transfer", "--init-from", "paper",
                                "--out", "runs/transfer", "--no-progress"), 227,
             "runs/transfer"),
        Step("ship_transfer", (py, "experiments/ship_policy.py", "runs/transfer", "transfer",
                               "--commit", commit, "--command", "python train.py --preset "
                               "transfer --init-from paper --out runs/transfer"), 5),
        Step("skill_paper", (py, "experiments/ship_policy.py", "policies/paper", "paper",
                             "--skill", "spiral"), 5),
        Step("skill_family", (py, "experiments/ship_policy.py", "policies/family", "family",
                              "--skill", "spiral", "--skill-constant", "yaw_scale=uncertainty"),
             5),
    ]
    small = ("--grid", "paper-small")

    def grid(name, expect_s, *args):
        argv = (py, "eval.py", "--out", f"{EVAL}/{name}", "--no-progress", *args)
        return Step(f"g_{name}", argv, expect_s, f"{EVAL}/{name}")

    paper = ("--policy", "paper")  # the skill its manifest names: spiral
    family = ("--policy", "family")
    per20 = (*small, "--trials", "20")
    better = ("--alternative", "greater")
    grids = [
        grid("paper_spiral_50mm_small_board", 194, *paper, *small, "--compare",
             f"{EVAL}/paper_align_50mm_small_board", *better),
        grid("paper_spiral_triangle_small_board", 228, *paper, *per20, "--shape", "triangle",
             "--paper", "triangle", "--compare", f"{EVAL}/paper_align_triangle_small_board",
             *better),
        grid("transfer_spiral_triangle_small_board", 183, "--policy", "transfer", *per20,
             "--shape", "triangle", "--paper", "transfer", "--compare",
             f"{EVAL}/paper_spiral_triangle_small_board", *better),
        grid("paper_spiral_25mm_small_board", 149, *paper, *per20, "--size", "25", "--paper",
             "25mm", "--compare", f"{EVAL}/paper_align_25mm_small_board", *better),
        grid("paper_spiral_60mm_small_board", 108, *paper, *per20, "--size", "60", "--paper",
             "60mm", "--compare", f"{EVAL}/paper_align_60mm_small_board", *better),
        grid("paper_spiral_50mm_small_flange", 241, *paper, *per20, "--grasp-model", "flange",
             "--paper", "nominal", "--compare", f"{EVAL}/paper_align_50mm_small_flange",
             *better),
        grid("baseline_spiral_50mm_small_board", 225, "--policy", "baseline", "--skill",
             "spiral", *small, "--compare", f"{EVAL}/paper_spiral_50mm_small_board",
             "--alternative", "less"),
        grid("family_spiral_50mm_small_board", 200, *family, *small, "--compare",
             f"{EVAL}/paper_spiral_50mm_small_board", "--alternative", "less"),
    ]

    def contact(name, expect_s, *args):
        argv = (py, "experiments/contact.py", *args, "--csv", f"{results}/contact/{name}.csv")
        return Step(name, argv, expect_s)

    base = ("--skill", "spiral")
    large = ("--linear-mm", "8", "--angular-deg", "12")
    more = ("--trials", "1500", "--seed", "2")
    sets = [
        contact("paper46", 21, *paper),
        contact("base46", 79, *base),
        contact("quick46", 44, "--policy", "quick"),
        contact("base46_paper_skill", 170, "--skill", "paper"),
        contact("paper812", 95, *paper, *large),
        contact("base812", 108, *base, *large),
        contact("quick812", 105, "--policy", "quick", *large),
        contact("quick812s2", 176, "--policy", "quick", *large, *more),
        contact("base812s2", 194, *base, *large, *more),
        contact("paper812s2", 180, *paper, *large, *more),
        contact("paper46s2", 128, *paper, *more),
        contact("base46s2", 129, *base, *more),
        contact("tri_transfer", 115, "--policy", "transfer", "--shapes", "triangle"),
        contact("tri_paper", 123, *paper, "--shapes", "triangle"),
        contact("tri_base", 116, *base, "--shapes", "triangle"),
        *(contact(f"sensor_{v}", 30, *paper, "--sensor", v)
          for v in ("nofilter", "cutoff0.5", "cutoff2", "delay+2", "noise2")),
        *(contact(f"friction_{f}", 85, *paper, "--friction", f) for f in ("0.2", "0.9")),
    ]
    zero = Step("zero", (py, "experiments/failures.py", *paper, "--linear-mm", "0",
                         "--angular-deg", "0", "--shape", "circle,square,triangle",
                         "--trials", "60", "--seed", "7", "--out", f"{results}/zero_error.npz"), 6)
    arm = []
    for shape in ("circle", "square"):
        for variant, extra in (("500", ()), ("lag", ("--actuator-lag-ms", "5")),
                               ("125", ("--command-hz", "125"))):
            name = f"arm_{shape}_{variant}"
            argv = (py, "-m", "mjx_peg.robot", *paper, "--shape", shape, "--linear-mm", "4",
                    "--angular-deg", "6", "--trials", "25", "--seed", "0", *extra, "--out",
                    f"{results}/arm/{name}")
            arm.append(Step(name, argv, 35, f"{results}/arm/{name}"))
    parts = Step("parts", (py, "experiments/parts_suite.py", "--policy", "baseline", "--policy",
                           "paper", *family, "--out", f"{results}/parts"), 3900,
                 f"{results}/parts")
    ur5e = Step("ur5e_table", (py, "experiments/ur5e_table.py", *paper, "--policy-for",
                               "triangle=transfer", "--out", f"{results}/ur5e_table"), 1050,
                f"{results}/ur5e_table")
    ur5e_family = Step("ur5e_table_family", (py, "experiments/ur5e_table.py", *family, "--out",
                                             f"{results}/ur5e_table_family"), 2040,
                       f"{results}/ur5e_table_family")
    vision = Step("vision", (py, "-m", "mjx_peg.vision", "act", *paper, "--out",
                             "docs/vision/act"), 310, "docs/vision/act")
    nominal = grid("paper_spiral_50mm_nominal_board", 1777, *paper, "--grid", "paper")
    family_nominal = grid("family_spiral_50mm_nominal_board", 1800, *family, "--grid", "paper",
                          "--compare", f"{EVAL}/paper_spiral_50mm_nominal_board",
                          "--alternative", "less")
    return [*train, *grids, *sets, zero, *arm, parts, ur5e, ur5e_family, vision, nominal,
            family_nominal]
    # fmt: on


def _head() -> str:
    return subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                          text=True, check=True).stdout.strip()  # fmt: skip


def _dirty() -> list[str]:
    """The changed files (against HEAD) of what trains and runs the trials."""
    paths = ["mjx_peg", "train.py", "eval.py", "scenes"]
    got = subprocess.run(["git", "status", "--porcelain", "--", *paths], cwd=ROOT,
                         capture_output=True, text=True, check=True)  # fmt: skip
    return [line[3:] for line in got.stdout.splitlines()]


def _minutes(seconds: float) -> str:
    return f"{seconds / 60:.0f} min" if seconds >= 90 else f"{seconds:.0f} s"


# The ETA scales what is left by the pace of the steps done once they were expected to take this
# long: a few seconds' step says nothing of the hours after it.
PACE_AFTER_S = 600.0


def left_s(expect_left: float, spent: float, expected: float) -> float:
    """The time the steps left should take: their expected seconds, at the pace of those done
    (`spent` of `expected` seconds) once PACE_AFTER_S of them are done."""
    return expect_left * (spent / expected if expected >= PACE_AFTER_S else 1.0)


def run(chosen: list[Step], out: Path, results: str = RESULTS) -> int:
    """Run the steps not yet done, one at a time, niced; then write the results page (where
    `results` is the shipped folder). 0, or 1 at the first step that fails."""
    todo = [s for s in chosen if not (out / f"{s.name}.done").exists()]
    for s in chosen:
        if s not in todo:
            print(f"{s.name}: done before, skipped")
    (ROOT / results / "contact").mkdir(parents=True, exist_ok=True)
    spent = expected = 0.0
    for k, step in enumerate(todo, 1):
        rest = left_s(sum(s.expect_s for s in todo[k - 1 :]), spent, expected)
        print(f"[{k}/{len(todo)}] {step.name} (~{_minutes(step.expect_s)}; all left ~"
              f"{_minutes(rest)})", flush=True)  # fmt: skip
        started = out / f"{step.name}.started"
        if step.fresh and not started.exists():
            shutil.rmtree(ROOT / step.fresh, ignore_errors=True)
        started.touch()
        t0 = time.monotonic()
        with open(out / f"{step.name}.log", "w") as log:
            rc = subprocess.call(step.argv, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT,
                                 preexec_fn=lambda: os.nice(10))  # fmt: skip
        wall = time.monotonic() - t0
        if rc != 0:
            print(f"{step.name} failed (exit {rc}) after {wall:.0f} s: see {out / step.name}.log",
                  file=sys.stderr)  # fmt: skip
            return 1
        (out / f"{step.name}.done").write_text(f"{wall:.1f}\n")
        spent, expected = spent + wall, expected + step.expect_s
        print(f"    done in {_minutes(wall)}", flush=True)
    print(f"every step done: the grids in {EVAL}/*/, the rest in {results}/, the logs in {out}/")
    if results != RESULTS:
        return 0  # the results page reads the shipped folder only
    from results_page import main as write_results_page  # this folder's; it imports this module

    return write_results_page([])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("runs/regenerate"),
                   help="logs, CSVs, markers (default: runs/regenerate)")  # fmt: skip
    p.add_argument("--only", default="", help="comma-separated fnmatch patterns of step names")
    p.add_argument(
        "--skip-nominal", action="store_true", help="not the nominal grids (30 min each)"
    )
    p.add_argument("--redo", default="",
                   help="comma-separated fnmatch patterns of steps to run again from their "
                   "start, done or not (a training's run folder, a grid's folder removed "
                   "first)")  # fmt: skip
    p.add_argument("--dry-run", action="store_true", help="print the commands, run nothing")
    p.add_argument("--results", default=RESULTS,
                   help=f"the contact sets, zero error and the arm's runs (default: {RESULTS}, "
                   "which the results page reads; elsewhere, the page is not written)")  # fmt: skip
    args = p.parse_args(argv)
    out = args.out if args.out.is_absolute() else Path.cwd() / args.out
    head = _head()
    chosen = steps(str(out), head, str(args.results))
    if args.only:
        patterns = [x for x in args.only.split(",") if x]
        chosen = [s for s in chosen if any(fnmatch.fnmatch(s.name, x) for x in patterns)]
        if not chosen:
            print(f"--only {args.only}: no step matches", file=sys.stderr)
            return 2
    if args.skip_nominal:
        chosen = [s for s in chosen if not s.name.endswith("_nominal_board")]
    if args.dry_run:
        for s in chosen:
            print(f"{s.name}: {shlex.join(s.argv)}")
        print(f"{len(chosen)} steps, ~{_minutes(sum(s.expect_s for s in chosen))} here")
        return 0
    if any(s.name.startswith("ship_") for s in chosen) and (dirty := _dirty()):
        print(f"the code has uncommitted changes ({', '.join(dirty[:3])}): the shipped policies' "
              "provenance names HEAD; commit first", file=sys.stderr)  # fmt: skip
        return 2
    out.mkdir(parents=True, exist_ok=True)
    mark = out / "commit"
    if mark.exists() and mark.read_text().strip() != head:
        print(f"--out {args.out} holds a regeneration of commit {mark.read_text().strip()[:7]}, "
              f"not of HEAD {head[:7]}: give a new --out", file=sys.stderr)  # fmt: skip
        return 2
    mark.write_text(head + "\n")
    redo = [x for x in args.redo.split(",") if x]
    again = [s for s in chosen if any(fnmatch.fnmatch(s.name, x) for x in redo)]
    if redo and not again:
        print(f"--redo {args.redo}: no chosen step matches", file=sys.stderr)
        return 2
    for s in again:
        for marker in ("done", "started"):  # no .started: its fresh path is removed at start
            (out / f"{s.name}.{marker}").unlink(missing_ok=True)
    try:
        return run(chosen, out, str(args.results))
    except KeyboardInterrupt:
        print("interrupted: rerun the same command to resume", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
