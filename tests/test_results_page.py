"""docs/results.md is what experiments/results_page.py writes from the shipped files, the
README's results table quotes it, and the docs' links lead somewhere."""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NUMBER = re.compile(r"(?<![\w.,])\d{1,3}(?:,\d{3})+(?![\w,])|(?<![\w.,])\d+(?:\.\d+)?(?![\w.])")


def numbers(text: str) -> set[str]:
    return set(NUMBER.findall(text))


def readme_results_table() -> str:
    """The first table under the README's `## Results`."""
    section = ROOT.joinpath("README.md").read_text().split("\n## Results\n", 1)[1]
    rows = [line for line in section.split("\n## ", 1)[0].splitlines() if line.startswith("|")]
    assert len(rows) > 3, "README's Results has no table"
    return "\n".join(rows)


def test_the_shipped_page_is_what_the_script_writes(tmp_path):
    out = tmp_path / "results.md"
    done = subprocess.run([sys.executable, ROOT / "experiments/results_page.py", "--out", out],
                          capture_output=True, text=True, cwd=ROOT)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert out.read_text() == ROOT.joinpath("docs/results.md").read_text(), (
        "docs/results.md differs from what experiments/results_page.py writes: rerun it"
    )


def test_every_number_of_the_readme_results_table_is_on_the_page():
    table = readme_results_table()
    page = numbers(ROOT.joinpath("docs/results.md").read_text())
    quoted = numbers(table)
    assert {"99.8", "96.96", "1.68", "70,000"} <= quoted  # the table's kind of numbers is read
    assert sorted(quoted - page) == []


def test_numbers_are_read_whole():
    assert numbers("| 98.6 (94.45) | Q1 | 1.58 / 2.61 s | 70,000 trials | ±8 mm |") == {
        "98.6", "94.45", "1.58", "2.61", "70,000", "8"
    }  # fmt: skip


def test_the_docs_links_lead_to_files():
    """Every relative Markdown link and image in README.md, BENCHMARKS.md and docs/ names a file
    that exists, and so does every `docs/...` path they quote."""
    missing = []
    for doc in [ROOT / "README.md", ROOT / "BENCHMARKS.md", *sorted(ROOT.glob("docs/**/*.md"))]:
        text = doc.read_text()
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if "://" not in target and not (doc.parent / target).exists():
                missing.append(f"{doc.relative_to(ROOT)}: {target}")
        for path in re.findall(r"`(docs/[\w./-]+?)/?`", text):
            if "NAME" not in path and "*" not in path and not (ROOT / path).exists():
                missing.append(f"{doc.relative_to(ROOT)}: {path}")
    assert missing == []


def test_a_learning_run_is_listed_with_the_command_that_makes_it_today():
    """A run whose start has changed since (the former generic start: the update held to a KL of
    0.01, the spiral pressing with a multiple of C_zz, its yaw unbounded and its peg upright) is
    listed with the flags that make it now, compared with the start's trials under its own skill,
    and the command of each shipped run resolves to that run's config."""
    import json

    sys.path.insert(0, str(ROOT / "experiments"))
    from results_page import start_set, train_command

    from mjx_peg.learn import cli
    from mjx_peg.learn.config import TrainConfig

    former = json.loads((ROOT / "docs/design/data/learning/scratch/seed-0/config.json").read_text())
    command = train_command(former, "scratch")
    assert command.endswith(
        "--kl-target 0.01 --skill-constant align_max_yaw=0 --skill-constant align_yaw_leak=inf "
        "--skill-constant spiral_axial_ref=0 --skill-constant spiral_tilt=0 --skill-constant "
        "spiral_yaw=0 --skill-constant spiral_yaw_period=2 --skill-constant insert_axial=0.5 "
        "--out runs/scratch"
    )
    start = start_set(former)
    assert start.name == "start-align_max_yaw=0-spiral_tilt=0.csv" and start.is_file()
    today = TrainConfig.from_json(former).replace(skill_constants=None).to_json()
    assert start_set(today).name == "base812s2.csv"
    argv = command.split()[2:]
    seeds = argv.index("--seeds")
    args = cli.parser().parse_args(argv[:seeds] + argv[seeds + 2 :] + ["--seed", "0"])
    made = TrainConfig.from_json(cli.resolve_config(args).to_json())
    assert made == TrainConfig.from_json(former)
