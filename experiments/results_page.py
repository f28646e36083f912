"""The results page, docs/results.md: every published number beside the command that makes it.

    python experiments/results_page.py               # writes docs/results.md
    python experiments/results_page.py --out FILE    # writes FILE instead

Written from the shipped result files alone, so that no number is typed twice: the evaluation
grids (`docs/eval/*/`: config.json, grid.csv, summary.md), the training runs (`policies/*/`:
provenance.json, config.json, metrics.csv), the contact sets, zero error and the simulated arm
(`docs/results/`), the localizer and vision to action (`docs/vision/`). A command is the step of
`experiments/regenerate.py` that writes the file where there is one, else the file's own record
of it (a grid's config.json, a policy's provenance.json). A new folder or file of these kinds
appears on the page without an edit here; `PAIRS` says which contact sets are compared.
`experiments/regenerate.py` runs this last; `tests/test_results_page.py` checks the shipped page.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import hashlib
import json
import re
import shlex
import sys
from pathlib import Path

import numpy as np
from contact_table import load, paired
from regenerate import EVAL, RESULTS, steps

ROOT = Path(__file__).resolve().parents[1]
PAGE = "docs/results.md"
SHIPPED_SKILL = "spiral"  # the skill of the headline table
CLI_SKILLS = ("paper", "spiral")  # eval.py's --skill; the others are experiments/ablations.py's
QUARTERS = ("Q1", "Q2", "Q3", "Q4")

# Contact sets compared on the same trials: (section, set, reference).
PAIRS = (
    ("What learning adds: a policy against its start, the baseline with the same skill",
     (("paper46", "base46"), ("quick46", "base46"), ("paper812", "base812"),
      ("quick812", "base812"), ("paper812s2", "base812s2"),
      ("quick812s2", "base812s2"),
      ("paper46s2", "base46s2"), ("tri_paper", "tri_base"),
      ("tri_transfer", "tri_base"),
      ("tri_transfer", "tri_paper"))),
    ("The shipped skill against the paper's, the baseline's numbers",
     (("base46", "base46_paper_skill"),)),
    ("Robustness: one thing of every trial changed",
     tuple((f"sensor_{v}", "paper46") for v in ("nofilter", "cutoff0.5", "cutoff2", "delay+2",
                                                 "noise2"))
     + (("friction_0.2", "paper46"), ("friction_0.9", "paper46"))),
)  # fmt: skip


def commands() -> dict[str, tuple[str, list[str]]]:
    """{output path: (step name, argv)} of every step of experiments/regenerate.py (`python` for
    its interpreter)."""
    out = {}
    for step in steps("runs/regenerate", "HEAD"):
        argv = ["python", *step.argv[1:]] if step.argv[0] == sys.executable else list(step.argv)
        for flag in ("--out", "--csv"):
            if flag in argv:
                out[argv[argv.index(flag) + 1]] = step.name, argv
    return out


def shell(argv) -> str:
    return f"`{shlex.join(argv)}`"


def pct(x: float) -> str:
    return f"{100 * x:.1f}"


def sha256(path: Path) -> str:
    return "sha256:" + hashlib.sha256(path.read_bytes()).hexdigest()


def flag(argv, name: str, default=None):
    """The value after `name` in argv, or `default`."""
    return argv[argv.index(name) + 1] if name in argv else default


def table(header: list[str], rows: list[list[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(r) + " |" for r in rows]


# --- evaluation grids ------------------------------------------------------------------------


class Grid:
    """One evaluation folder: its config, its summary's numbers, the command that made it."""

    def __init__(self, folder: Path, made_by: dict):
        self.name = folder.name
        self.path = f"{EVAL}/{folder.name}"
        record = json.loads((folder / "config.json").read_text())
        self.config = c = record["config"]
        self.skill = c.get("skill") or "paper"  # evaluations before the option ran the paper's
        self.policy = record.get("policy_dir") or "baseline"
        shipped = ROOT / "policies" / self.policy / "policy.npz"
        self.shipped = self.policy == "baseline" or (
            shipped.exists() and sha256(shipped) == c["policy"]
        )
        text = (folder / "summary.md").read_text()
        sections = {s.split("\n", 1)[0]: s for s in text.split("\n## ")}
        self.success = self._means(sections["Success rate per quarter (%)"])
        self.time = self._means(sections["Mean time to complete per quarter (s)"])
        label = re.search(r"In brackets: the paper's numbers, (.+?) \(", text)
        self.paper = label[1] if label else ""
        with open(folder / "grid.csv") as f:
            ranges = list(csv.DictReader(f))
        self.trials = sum(int(r["trials"]) for r in ranges)
        self.successes = sum(int(r["successes"]) for r in ranges)
        self.stops = sum(int(r["protective_stops"]) for r in ranges)
        self.steps = int(re.search(r"simulated: (\d+) physics steps", text)[1])
        self.order = self._order(sections["Quarter-order tests"])
        self.failures = self._failures(sections.get("Failures", ""))
        self.against = next((s for s in sections if s.startswith("Against ")), None)
        self.tests = self._tests(sections[self.against]) if self.against else {}
        self.argv = made_by.get(self.path) or self._argv()

    @staticmethod
    def _means(section: str) -> list[tuple[str, str | None]]:
        """[(ours, the paper's or None)] per quarter, from the section's `mean` row."""
        row = next(line for line in section.splitlines() if line.startswith("| mean |"))
        cells = [c.strip() for c in row.strip("|").split("|")[1:]]
        return [(m[1], m[2]) for m in (re.fullmatch(r"(\S+)(?: \((\S+)\))?", c) for c in cells)]

    @staticmethod
    def _order(section: str) -> tuple[int, int]:
        """(pairs of quarters ordered as the paper orders them, pairs compared)."""
        rows = [[c.strip() for c in line.strip("|").split("|")] for line in section.splitlines()
                if line.startswith("| Q")]  # fmt: skip
        rows = [r for r in rows if r[6] != "-"]  # "-": the paper gives no order for it
        return sum(r[5] == r[6] for r in rows), len(rows)

    @staticmethod
    def _failures(section: str) -> list[tuple[str, int]]:
        rows = [line.strip("|").split("|") for line in section.splitlines()
                if line.startswith("| ") and not line.startswith("| failure")]  # fmt: skip
        return [(r[0].strip(), int(r[1])) for r in rows]

    @staticmethod
    def _tests(section: str) -> dict[tuple[str, str], tuple[str, str]]:
        """{(metric, quarter): (alternative, p)} of the per-quarter tests against another grid."""
        out = {}
        for line in section.splitlines():
            cells = [c.strip() for c in line.strip("|").split("|")]
            if len(cells) >= 8 and cells[0] in QUARTERS:
                out[cells[1], cells[0]] = cells[2], cells[7]
        return out

    def _argv(self) -> list[str]:
        """The eval.py command of this folder, rebuilt from its config.json and summary.md."""
        c = self.config
        argv = ["python", "eval.py", "--policy", self.policy, "--grid", c["grid"]]
        if c["grid"] == "custom":
            argv += ["--linear-mm", ",".join(f"{v:g}" for v in c["linear_mm"]),
                     "--angular-deg", ",".join(f"{v:g}" for v in c["angular_deg"])]  # fmt: skip
        argv += ["--trials", str(c["trials"])]
        if c["shapes"] != ["circle", "square"]:
            argv += ["--shape", ",".join(c["shapes"])]
        if c["size_mm"] != 50:
            argv += ["--size", f"{c['size_mm']:g}"]
        if c.get("grasp_model", "board") != "board":
            argv += ["--grasp-model", c["grasp_model"]]
        if c.get("skill"):
            argv += ["--skill", c["skill"]]
        if c["seed"] != 0:
            argv += ["--seed", str(c["seed"])]
        if "transfer" in self.paper:
            argv += ["--paper", "transfer"]
        argv += ["--out", self.path]
        if self.against:
            alternative = next(iter(self.tests.values()))[0].split()[-1]
            argv += ["--compare", self.against.split()[1], "--alternative", alternative]
        return argv

    def order(self) -> tuple:
        """The headline first; then by skill and condition (the nominal grid, the board model,
        circle and square, 50 mm first), then policy."""
        c = self.config
        return (not self.headline, self.skill, c["grid"] != "paper",
                c.get("grasp_model", "board") != "board", c["shapes"] != ["circle", "square"],
                self.policy, c["size_mm"] != 50, c["size_mm"], self.name)  # fmt: skip

    def command(self) -> str:
        """Its command, and what keeps it from reproducing the folder today, if anything."""
        notes = []
        if self.skill not in CLI_SKILLS:
            notes.append(f"`{self.skill}` is an ablation now (experiments/ablations.py), not a "
                         "choice of eval.py")  # fmt: skip
        if not self.shipped:
            notes.append(f"its policy, {self.config['policy'][:19]}, is not shipped")
        return shell(self.argv) + (f" (as it ran; {'; '.join(notes)})" if notes else "")

    @property
    def headline(self) -> bool:
        """A shipped policy with the shipped skill: a row of the table against the paper."""
        return self.skill == SHIPPED_SKILL and self.shipped and self.policy != "baseline"

    def condition(self) -> str:
        c = self.config
        shapes = " + ".join(c["shapes"])
        grasp = ", the flange model" if c.get("grasp_model") == "flange" else ""
        return (f"`{c['grid']}`, {shapes} {c['size_mm']:g} mm{grasp}, {c['trials']} per range "
                f"({self.trials:,} trials)")  # fmt: skip

    def controller(self) -> str:
        if self.policy == "baseline":
            return "the baseline"
        name = f"`{self.policy}`" if self.shipped else f"`{Path(self.policy).name}`"
        return name if self.shipped else f"{name} (not shipped)"

    def quarters(self, values, ours=lambda v: v) -> list[str]:
        return [ours(v) + (f" ({p})" if p else "") for v, p in values]

    def times(self) -> str:
        ours = " / ".join(v for v, _ in self.time)
        paper = " / ".join(p for _, p in self.time if p)
        return ours + (f" ({paper})" if paper and len(paper.split(" / ")) == 4 else "")


def grids(made_by) -> list[Grid]:
    folders = sorted(p.parent for p in (ROOT / EVAL).glob("*/summary.md"))
    out = [Grid(f, made_by) for f in folders if (f / "config.json").exists()]
    return sorted(out, key=Grid.order)


def success1(value: str) -> str:
    return f"{float(value):.1f}"


def grid_sections(all_grids: list[Grid]) -> list[str]:
    head = [g for g in all_grids if g.headline]
    lines = [
        "## Against the paper",
        "",
        f"The shipped policies with the shipped skill (`{SHIPPED_SKILL}`) on the paper's grids, "
        "mean success per quarter (%) and mean time to complete per quarter (s), the paper's "
        "numbers in brackets (its Tables 4-5 for the condition each `summary.md` names). "
        "Quarters: Q1 small linear and angular errors, Q2 large angular, Q3 large linear, "
        "Q4 both large.",
        "",
    ]
    rows = [[g.condition(), g.controller(), *g.quarters(g.success, success1), g.times()]
            for g in head]  # fmt: skip
    lines += table(["condition", "policy", *QUARTERS, "mean time per quarter (s)"], rows)
    lines += ["", "Commands (each writes the folder under `docs/eval/` named in it):", ""]
    lines += [f"- {g.command()}" for g in head]
    lines += [
        "",
        "## Every evaluation grid",
        "",
        "Each `docs/eval/` folder: its controller and skill, success over all trials, the "
        "pairs of quarters whose order (one-sided Mann-Whitney U tests, success and time) is "
        "the paper's, success per quarter (%), mean time per quarter (s), physics steps per "
        "trial (the grid's cost), protective stops, and how the failures ended (`summary.md`'s "
        "taxonomy; *above the board*: withdrawn after the spiral's search budget).",
        "",
    ]
    rows = []
    for g in all_grids:
        failures = ", ".join(f"{n} {name}" for name, n in g.failures) or "-"
        order = f"{g.order[0]} / {g.order[1]}" if g.order[1] else "-"
        rows.append([f"`{g.name}`", g.controller(), g.skill,
                     f"{100 * g.successes / g.trials:.1f} %", order,
                     *(success1(v) for v, _ in g.success), " / ".join(v for v, _ in g.time),
                     f"{round(g.steps / g.trials):,}", str(g.stops), failures])  # fmt: skip
    header = ["folder", "policy", "skill", "all trials", "quarters' order as the paper's",
              *QUARTERS, "time per quarter (s)",
              "steps per trial", "protective stops", "failures"]  # fmt: skip
    lines += table(header, rows)
    lines += ["", "Commands:", ""]
    lines += [f"- `{g.name}`: {g.command()}" for g in all_grids]
    compared = [g for g in all_grids if g.tests]
    lines += [
        "",
        "## Grids against grids",
        "",
        "One-sided Mann-Whitney U tests over the per-range values of each quarter "
        "(`summary.md`, `--compare`): p of this grid being better than the other (where the "
        "alternative says *greater*: a higher success rate, a shorter time) or worse (*less*: a "
        "lower success rate, a longer time).",
        "",
    ]
    rows = []
    for g in compared:
        other = g.against.split()[1].split("/")[-1]
        alternative = g.tests["success", "Q1"][0]
        rows.append([f"`{g.name}`", f"`{other}`", alternative,
                     *(f"{float(g.tests['success', q][1]):.2g}" for q in QUARTERS),
                     *(f"{float(g.tests['time', q][1]):.2g}" for q in QUARTERS)])  # fmt: skip
    header = ["grid", "against", "success", *(f"p success {q}" for q in QUARTERS),
              *(f"p time {q}" for q in QUARTERS)]  # fmt: skip
    return lines + table(header, rows)


# --- training --------------------------------------------------------------------------------


def minutes(seconds: float) -> str:
    return f"{seconds:,.0f} s ({int(seconds // 60)} min {seconds % 60:.0f} s)"


def training_section() -> list[str]:
    lines = [
        "## Training",
        "",
        "Each shipped policy (`policies/NAME`, `--policy NAME` in every command): the command "
        "and commit that made it, its trials, the skill it trained with and the one it runs "
        "unless told otherwise (its manifest), the run's wall time on "
        "this 2-core CPU and the training success (the mean of the first and of the last three "
        "iterations), from its `provenance.json`, `config.json` and `metrics.csv`.",
        "",
    ]
    rows, cmds = [], []
    for folder in sorted((ROOT / "policies").glob("*/provenance.json")):
        folder = folder.parent
        made = json.loads((folder / "provenance.json").read_text())
        config = json.loads((folder / "config.json").read_text())
        runs = json.loads((folder / "manifest.json").read_text()).get("skill", {}).get("name")
        with open(folder / "metrics.csv") as f:
            metrics = list(csv.DictReader(f))
        rate = [float(m["success_rate"]) for m in metrics]
        errors = f"±{config['linear_mm']:g} mm / ±{config['angular_deg']:g} deg"
        rows.append([f"`{folder.name}`", " + ".join(config["shapes"]), errors,
                     f"{int(metrics[-1]['trials']):,}", config["skill"], runs or config["skill"],
                     minutes(float(metrics[-1]["wall_s"])),
                     f"{pct(np.mean(rate[:3]))} -> {pct(np.mean(rate[-3:]))} %",
                     made["commit"][:7]])  # fmt: skip
        cmds.append(f"- `{folder.name}`: `{made['command']}`")
    header = ["policy", "shapes", "errors", "trials", "trained with", "runs by default", "wall",
              "training success", "commit"]  # fmt: skip
    return lines + table(header, rows) + ["", "Commands:", "", *cmds]


LEARNING = "docs/design/data/learning"


def train_options(config: dict, name: str) -> tuple[list[str], list[str]]:
    """(the start's options, the changes' options) of the train.py command that makes the runs
    of `config` (a seed's config.json) today: its preset and start; the update's KL and the
    skill's constants where they differ from what those give now (an earlier run of a start
    whose settings have since changed: `--skill-constant NAME=VALUE` each)."""
    from mjx_peg.learn import cli
    from mjx_peg.learn.config import TrainConfig

    want = TrainConfig.from_json(config)
    start = [] if want.preset == "quick" else ["--preset", want.preset]
    start += [] if want.prior == "baseline" else ["--prior", want.prior]
    start += ["--eval-every", str(want.eval_every)]

    def made(extra):
        args = cli.parser().parse_args([*start, *extra, "--seed", str(want.seed)])
        return TrainConfig.from_json(cli.resolve_config(args).to_json())

    got, extra = made([]), []
    if got.kl_target != want.kl_target:
        extra += ["--kl-target", f"{want.kl_target:g}"]
    for field in dataclasses.fields(want.skill_constants):
        value = getattr(want.skill_constants, field.name)
        if value != getattr(got.skill_constants, field.name):
            extra += ["--skill-constant", f"{field.name}={value:g}"]
    if made(extra) != want:
        raise ValueError(f"{name}: no train.py command of its preset, start, KL and skill "
                         "constants makes its config.json")  # fmt: skip
    return start, extra


def train_command(config: dict, name: str) -> str:
    """The train.py command that makes the runs of `config` today (`train_options`)."""
    start, extra = train_options(config, name)
    head = start[:-2]  # --eval-every after --seeds, as the guides write it
    return shlex.join(["python", "train.py", *head, "--seeds", "0,1,2", *start[-2:], *extra,
                       "--out", f"runs/{name}"])  # fmt: skip


def start_set(config: dict) -> Path:
    """The hand-tuned start's 1,500 trials under the skill the run of `config` trained with: a
    set kept from before constants of the skill changed, named by their values then
    (`LEARNING/contact/start-NAME=VALUE[-NAME=VALUE...].csv`), where the run's constants hold
    each; else the shipped set (`docs/results/contact/base812s2.csv`, today's skill)."""
    from mjx_peg.learn.config import TrainConfig

    constants = TrainConfig.from_json(config).skill_constants
    for path in sorted((ROOT / LEARNING / "contact").glob("start-*.csv")):
        pairs = [item.partition("=") for item in path.stem.removeprefix("start-").split("-")]
        if all(getattr(constants, name) == float(value) for name, _, value in pairs):
            return path
    return ROOT / RESULTS / "contact" / "base812s2.csv"


def learning_section() -> list[str]:
    """The learning runs over seeds (docs/design/learning_from_scratch.md): each run's held-out
    curve and its mean on the 1,500 trials at the paper's training errors, against its start."""
    root = ROOT / LEARNING
    if not root.exists():
        return []
    lines = [
        "## Learning over seeds",
        "",
        "Runs that learn the skill's 47 numbers, one row per seed (files under "
        f"`{LEARNING}/`; the question and the decisions: "
        "`docs/design/learning_from_scratch.md`): the held-out success of the policy's mean (128 "
        "fixed trials, 20 s) at the end, its first and last held-out points, and where measured "
        "its mean on the 1,500 trials at ±8 mm / ±12 deg (seed 2, 60 s) against the hand-tuned "
        "start on the same trials under the run's own skill (McNemar; "
        "`docs/results/contact/base812s2.csv`, or for a run of the skill before a constant "
        f"changed the start's set then, `{LEARNING}/contact/start-NAME=VALUE.csv`).",
        "",
    ]
    rows, cmds = [], {}
    for folder in sorted(root.glob("*/seed-*")):
        config = json.loads((folder / "config.json").read_text())
        start = load(start_set(config))
        with open(folder / "eval.csv") as f:
            held = list(csv.DictReader(f))
        first, last = held[0], held[-1]
        contact = root / "contact" / f"{folder.parent.name}-{folder.name}.csv"
        cell = ""
        if contact.exists():
            run = load(contact)
            lost, gained, p, change = paired(run, start, contact.name)
            cell = (f"{pct(np.mean(run['success'] > 0.5))} %, {change:+.1f} ({lost} lost / "
                    f"{gained} gained, p = {p:.2g})")  # fmt: skip
        curve = (f"{pct(float(first['success_rate']))} % at {int(first['trials']):,} -> "
                 f"{pct(float(last['success_rate']))} % at {int(last['trials']):,}")  # fmt: skip
        rows.append([f"`{folder.parent.name}/{folder.name}`", config["prior"],
                     f"{int(config['trials']):,}", curve, cell])  # fmt: skip
        cmds[folder.parent.name] = train_command(config, folder.parent.name)
    header = ["run", "start", "trials", "held-out success", "the 1,500 trials, against the start"]
    listed = [f"- `{name}`: `{command}`" for name, command in cmds.items()]
    return lines + table(header, rows) + ["", "Commands:", "", *listed]


# --- contact sets ----------------------------------------------------------------------------


def describe(argv: list[str]) -> tuple[str, str]:
    """(the controller, the trials) of an experiments/contact.py command."""
    policy = flag(argv, "--policy", "baseline")
    who = "the baseline" if policy == "baseline" else f"`{policy}`"
    skill = flag(argv, "--skill")
    who += f", `{skill}`" if skill else ""
    if (search := flag(argv, "--search")) is not None:
        who += f" with `{search}`"
    if (sensor := flag(argv, "--sensor")) is not None:
        who += f", sensor `{sensor}`"
    if (friction := flag(argv, "--friction")) is not None:
        who += f", friction {friction}"
    shapes = " + ".join(flag(argv, "--shapes", "circle,square").split(","))
    trials = (f"{shapes} {flag(argv, '--size-mm', '50')} mm, ±{flag(argv, '--linear-mm', '4')} "
              f"mm / ±{flag(argv, '--angular-deg', '6')} deg, {flag(argv, '--trials', '500')} "
              f"trials, seed {flag(argv, '--seed', '1')}")  # fmt: skip
    return who, trials


def contact_section(made_by) -> list[str]:
    folder = ROOT / RESULTS / "contact"
    found = {p.stem: p for p in sorted(folder.glob("*.csv"))}
    if not found:
        return []
    order = [Path(k).stem for k in made_by if k.startswith(f"{RESULTS}/contact/")]
    names = [n for n in order if n in found] + sorted(set(found) - set(order))
    sets = {n: load(found[n]) for n in names}
    argv = {n: made_by.get(f"{RESULTS}/contact/{n}.csv", ["(no command recorded)"]) for n in names}
    lines = [
        "## Contact sets",
        "",
        "Fixed sets of trials (`experiments/contact.py`, one row per trial in "
        "`docs/results/contact/NAME.csv`): success, protective stops, time to insert of the "
        "successes (p10 / p50 / p90) and the peak sensed force (median / p99).",
        "",
    ]
    rows = []
    for n in names:
        run = sets[n]
        ok = run["success"] > 0.5
        t = np.percentile(run["time_s"][ok], [10, 50, 90]) if ok.any() else [np.nan] * 3
        peak = np.percentile(run["peak_force"], [50, 99])
        who, trials = describe(argv[n])
        rows.append([f"`{n}`", who, trials, f"{pct(ok.mean())} % ({int(ok.sum())} / {ok.size})",
                     str(int(run["protective_stop"].sum())), " / ".join(f"{v:.1f}" for v in t),
                     f"{peak[0]:.0f} / {peak[1]:.0f} N"])  # fmt: skip
    header = ["set", "controller", "trials", "success", "protective stops",
              "insert p10 / p50 / p90 (s)", "peak force"]  # fmt: skip
    lines += table(header, rows) + ["", "Commands:", ""]
    lines += [f"- `{n}`: {shell(argv[n])}" for n in names]
    for title, pairs in PAIRS:
        pairs = [(a, b) for a, b in pairs if a in sets and b in sets]
        if not pairs:
            continue
        lines += ["", f"### {title}", "",
                  "Paired on the same trials: the change in success points, the trials lost and "
                  "gained, the exact McNemar p (two-sided).", ""]  # fmt: skip
        rows = []
        for a, b in pairs:
            lost, gained, p, change = paired(sets[a], sets[b], a)
            rows.append([f"`{a}`", f"`{b}`", f"{pct((sets[a]['success'] > 0.5).mean())} %",
                         f"{pct((sets[b]['success'] > 0.5).mean())} %", f"{change:+.1f}",
                         f"{lost} / {gained}", f"{p:.2g}"])  # fmt: skip
        lines += table(["set", "against", "success", "its success", "points", "lost / gained",
                        "McNemar p"], rows)  # fmt: skip
    return lines


# --- zero error, the simulated arm, vision ---------------------------------------------------


def zero_section(made_by) -> list[str]:
    path = f"{RESULTS}/zero_error.npz"
    if not (ROOT / path).exists():
        return []
    data = np.load(ROOT / path, allow_pickle=False)
    shapes = sorted({k.split("/")[0] for k in data.files}, key=["circle", "square",
                                                                 "triangle"].index)  # fmt: skip
    rows = []
    for s in shapes:
        ok = data[f"{s}/result/success"]
        peak = np.percentile(data[f"{s}/result/peak_force"], [50, 99])
        rows.append([s, f"{int(ok.sum())} / {ok.size}",
                     str(int(data[f"{s}/result/protective_stop"].sum())),
                     f"{peak[0]:.0f} / {peak[1]:.0f} N"])  # fmt: skip
    lines = [
        "## Zero error",
        "",
        "No localization or grasp error at all: every trial should insert.",
        "",
    ]
    lines += table(["shape", "success", "protective stops", "peak force median / p99"], rows)
    return lines + ["", f"Command: {shell(made_by.get(path, ['(no command recorded)']))}"]


def arm_section(made_by) -> list[str]:
    runs = sorted((ROOT / RESULTS / "arm").glob("*/runs.csv"))
    if not runs:
        return []
    rows, cmds = [], []
    for path in runs:
        key = f"{RESULTS}/arm/{path.parent.name}"
        argv = made_by.get(key, [])
        with open(path) as f:
            trials = list(csv.DictReader(f))
        ok = np.array([int(t["success"]) for t in trials])
        peak = np.median([float(t["peak_force_n"]) for t in trials])
        hz = flag(argv, "--command-hz", "500")
        lag = flag(argv, "--actuator-lag-ms")
        variant = f"{hz} Hz commands" + (f", actuator lag {lag} ms" if lag else "")
        rows.append([f"`{path.parent.name}`", flag(argv, "--shape", "?"), variant,
                     f"{pct(ok.mean())} % ({int(ok.sum())} / {ok.size})",
                     str(sum(int(t["protective_stop"]) for t in trials)),
                     f"{peak:.0f} N"])  # fmt: skip
        cmds.append(f"- `{path.parent.name}`: {shell(argv or ['(no command recorded)'])}")
    lines = ["## The simulated arm", "",
             "The NumPy robot runtime on a simulated UR5e (`python -m mjx_peg.robot`), one "
             "trial after another, `runs.csv` per run under `docs/results/arm/`.", ""]  # fmt: skip
    header = ["run", "shape", "variant", "success", "protective stops", "peak force median"]
    return lines + table(header, rows) + ["", "Commands:", "", *cmds]


def parts_section(made_by) -> list[str]:
    """The parts suite's table (experiments/parts_suite.py writes it) and its figure."""
    folder = ROOT / RESULTS / "parts"
    if not (folder / "parts.md").exists():
        return []
    argv = made_by.get(f"{RESULTS}/parts", ["(no command recorded)"])
    lines = ["## The parts suite", "", *(folder / "parts.md").read_text().rstrip("\n").split("\n")]
    return lines + [
        "",
        "![the parts suite](results/parts/parts.png)",
        "",
        f"Command: {shell(argv)}",
    ]


def ur5e_section(made_by) -> list[str]:
    """The paper's UR5e table in simulation (experiments/ur5e_table.py writes it): with `paper`
    (`transfer` for the triangles), then with `family` where it ran."""
    lines = []
    for name, title in (("ur5e_table", "## The paper's UR5e table"),
                        ("ur5e_table_family", "### The same table with `family`")):  # fmt: skip
        folder = ROOT / RESULTS / name
        if not (folder / "table.md").exists():
            continue
        argv = made_by.get(f"{RESULTS}/{name}", ["(no command recorded)"])
        text = (folder / "table.md").read_text().rstrip("\n").split("\n")
        lines += [*([""] if lines else []), title, "", *text, "", f"Command: {shell(argv)}"]
    return lines


def vision_section(made_by) -> list[str]:
    lines = []
    evals = sorted((ROOT / "docs/vision/eval").glob("*/metrics.json"))
    if evals:
        lines += ["## The localizer", "",
                  "Error of the estimated hole centre on the table (mm) and of the yaw modulo "
                  "the shape's symmetry (deg), p50 / p95 / p99; the share of estimates within "
                  "the paper's 8 mm / 8 deg (`docs/vision/eval/NAME/`; measured with a localizer "
                  "trained by the same commands as the shipped one, whose estimates agree with "
                  "it: `docs/design/localizer.md`).", ""]  # fmt: skip
        rows, cmds = [], []
        for path in evals:
            m = json.loads(path.read_text())["overall"]
            name = path.parent.name
            head = (path.parent / "summary.md").read_text().splitlines()[0]
            count, seed, condition = re.search(r"\((\d+) renders, seed (\d+), condition (\S+),",
                                               head).groups()  # fmt: skip
            pos = " / ".join(f"{m[f'pos_p{q}_mm']:.2f}" for q in (50, 95, 99))
            yaw = " / ".join(f"{m[f'yaw_p{q}_deg']:.2f}" for q in (50, 95, 99))
            rows.append([f"`{name}`", f"{m['images']:,}", pos, yaw,
                         f"{pct(m['shape_accuracy'])} / {pct(m['size_accuracy'])} %",
                         f"{pct(m['within_paper_bar'])} %"])  # fmt: skip
            data = f"runs/vision/data/{name}"
            render = ["mjx-peg-vision", "render", "--out", data, "--count", count, "--seed", seed]
            render += ["--condition", condition] if condition != "nominal" else []
            cmds.append(f"- `{name}`: {shell(render)}, then "
                        f"{shell(['mjx-peg-vision', 'evaluate', '--data', data, '--out', str(path.parent.relative_to(ROOT))])}")  # noqa: E501  # fmt: skip
        header = ["renders", "images", "position (mm)", "yaw (deg)", "shape / size correct",
                  "within 8 mm / 8 deg"]  # fmt: skip
        lines += table(header, rows) + ["", "Commands:", "", *cmds, ""]
    act = ROOT / "docs/vision/act/summary.json"
    if act.exists():
        s = json.loads(act.read_text())
        lines += ["## Vision to action", "",
                  f"`{Path(s['policy']).name}` with the skill `{s['skill']}`, "
                  f"{s['trials_per_shape']} trials per shape at {s['size_mm']:g} mm, grasp "
                  "errors at the paper's maxima, the hole from the shipped localizer on a render "
                  "of each board; the same trials with the hole drawn within ±8 mm / ±12 deg "
                  "and with its exact pose (McNemar p against vision).", ""]  # fmt: skip
        rows = []
        for name, r in [*s["shapes"].items(), ("all", s["all"])]:
            rows.append([name, f"{pct(r['vision_success'])} %",
                         f"{pct(r['sampled_success'])} % (p = {r['mcnemar_p']:.2g})",
                         f"{pct(r['exact_success'])} % (p = {r['mcnemar_p_vision_exact']:.2g})",
                         f"{pct(s['all']['paper_success'])} %"])  # fmt: skip
        lines += table(["shape", "vision", "sampled error", "exact pose", "the paper (vision)"],
                       rows)  # fmt: skip
        argv = made_by.get("docs/vision/act", ["(no command recorded)"])
        lines += ["", f"Command: {shell(argv)}"]
    return lines


def page() -> str:
    """The whole of docs/results.md."""
    made = commands()
    made_by = {path: argv for path, (_, argv) in made.items()}
    lines = [
        "# Results",
        "",
        "Every published number of this project, each beside the command that reproduces it, "
        "on this 2-core CPU. Written by `python experiments/results_page.py` (the last step of "
        "`python experiments/regenerate.py`) from the shipped result files: do not edit it by "
        "hand. What the numbers mean and how to run each command: the guides (`docs/guide/`); "
        "speed: `BENCHMARKS.md`; how the skill got here: `docs/design/`.",
        "",
        *grid_sections(grids(made_by)),
        "",
        *training_section(),
    ]
    if part := learning_section():
        lines += ["", *part]
    for section in (
        contact_section,
        parts_section,
        ur5e_section,
        zero_section,
        arm_section,
        vision_section,
    ):
        if part := section(made_by):
            lines += ["", *part]
    missing = [name for path, (name, _) in made.items()
               if path.startswith("docs/") and not (ROOT / path).exists()]  # fmt: skip
    if missing:
        lines += ["", "## Not on this page yet", "",
                  "These steps of `experiments/regenerate.py` have no shipped output; their "
                  "numbers appear here once they have run: "
                  f"`python experiments/regenerate.py --only '{','.join(missing)}'`."]  # fmt: skip
    return "\n".join(lines).rstrip("\n") + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=ROOT / PAGE, help=f"default: {PAGE}")
    args = p.parse_args(argv)
    args.out.write_text(page())
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
