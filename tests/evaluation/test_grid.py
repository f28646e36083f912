"""The evaluation grid: quarter statistics, Mann-Whitney U by hand, heatmaps, resume, bad input."""

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mjx_peg import cli
from mjx_peg.evaluation import config as eval_config
from mjx_peg.evaluation import eval_cli, eval_dir, grid_table, runner, summary
from mjx_peg.evaluation import stats as es
from mjx_peg.evaluation.paper_tables import PAPER, paper_order_conclusion
from mjx_peg.evaluation.plots import (
    grid_matrix,
    paper_bars,
    quarter_stats_by_metric,
    success_heatmap,
    time_heatmap,
)
from mjx_peg.policy.export import policy_skill

REPO = Path(__file__).resolve().parents[2]
PAPER_TEX = REPO.parent / "shared" / "paper" / "spector-zacksenhouse-compliant-dmp.tex"

# A 4 x 4 synthetic grid (linear 1-4 mm, angular 1-4 deg): four ranges per quarter.
QUARTER_SUCCESS = {  # per-range success rate (%), 100 trials per range
    "Q1": [100, 98, 96, 94],
    "Q2": [96, 94, 92, 90],
    "Q3": [94, 92, 90, 88],
    "Q4": [90, 92, 95, 80],
}
QUARTER_TIME = {
    "Q1": [1.0, 1.2, 1.4, 1.6],
    "Q2": [2, 2, 2.5, 3],
    "Q3": [3, 4, 5, 6],
    "Q4": [4, 5, 6, 7],
}


def synthetic_grid() -> grid_table.GridTable:
    linear, angular, success, times = [], [], [], []
    where = {"Q1": (0, 0), "Q2": (0, 2), "Q3": (2, 0), "Q4": (2, 2)}  # (linear, angular) offset
    for q, (li, ai) in where.items():
        for k in range(4):
            linear.append(1.0 + li + k // 2)
            angular.append(1.0 + ai + k % 2)
            success.append(QUARTER_SUCCESS[q][k])
            times.append(QUARTER_TIME[q][k])
    trials = np.full(16, 100)
    times = np.array(times, dtype=float)
    return grid_table.GridTable(
        linear_mm=np.array(linear),
        angular_deg=np.array(angular),
        trials=trials,
        successes=np.array(success),
        time_mean_s=times,
        time_min_s=times - 0.5,
        time_max_s=times + 0.5,
    )


def test_quarters_split_each_axis_at_its_middle():
    grid = synthetic_grid()
    for q in es.QUARTERS:
        np.testing.assert_array_equal(
            np.sort(grid.success_pct[grid.quarter == q]), np.sort(QUARTER_SUCCESS[q])
        )
    # The paper grid: 25 linear ranges (12 small), 14 angular (7 small, up to 6 deg).
    lin, ang, trials = eval_config.PRESETS["paper"]
    assert (len(lin), len(ang), trials) == (25, 14, 200)
    assert lin[0] == pytest.approx(0.32) and lin[-1] == pytest.approx(8.0)
    assert ang[0] == pytest.approx(12 / 14) and ang[-1] == pytest.approx(12.0)
    ll, aa = np.meshgrid(lin, ang, indexing="ij")
    quarters = es.quarter_labels(ll.ravel(), aa.ravel())
    counts = {q: int((quarters == q).sum()) for q in es.QUARTERS}
    assert counts == {"Q1": 12 * 7, "Q2": 12 * 7, "Q3": 13 * 7, "Q4": 13 * 7}
    assert set(quarters[(ll.ravel() < 4.0) & (aa.ravel() <= 6.0 + 1e-9)]) == {"Q1"}


def test_quarter_statistics_by_hand():
    grid = synthetic_grid()
    stats = es.quarter_stats(grid.success_pct, grid.quarter)
    assert stats["Q1"] == es.QuarterStats(4, 97.0, 94.0, 100.0)
    assert stats["Q4"] == es.QuarterStats(4, 89.25, 80.0, 95.0)
    times = es.quarter_stats(grid.time_mean_s, grid.quarter)
    assert times["Q2"].mean == pytest.approx(2.375) and times["Q3"].max == 6.0
    # Ranges without a success have no time: left out, and a quarter without data is NaN.
    t = grid.time_mean_s.copy()
    t[grid.quarter == "Q3"] = np.nan
    t[np.flatnonzero(grid.quarter == "Q1")[0]] = np.nan
    stats = es.quarter_stats(t, grid.quarter)
    assert stats["Q1"].n == 3 and stats["Q1"].mean == pytest.approx(1.4)
    assert stats["Q3"].n == 0 and math.isnan(stats["Q3"].mean)


def test_mann_whitney_exact_by_hand():
    """Q1 [100, 98, 96, 94] vs Q4 [90, 92, 95, 80]: 15 of 16 pairs favour Q1, no ties.

    Exact null distribution: of the C(8, 4) = 70 equally likely rank sets, one gives U = 16 and
    one U = 15, so P(U >= 15) = 2 / 70.
    """
    test = es.mann_whitney(QUARTER_SUCCESS["Q1"], QUARTER_SUCCESS["Q4"], "greater")
    assert test.u == 15.0 and (test.n_x, test.n_y) == (4, 4)
    assert test.p == pytest.approx(2 / 70, rel=1e-12)
    assert test.significant
    # The other direction: P(U' <= 1) ... U' = 16 - 15 = 1 for Q4, P(U_Q4 >= 1) = 69 / 70.
    other = es.mann_whitney(QUARTER_SUCCESS["Q4"], QUARTER_SUCCESS["Q1"], "greater")
    assert other.u == 1.0 and other.p == pytest.approx(69 / 70, rel=1e-12)
    assert not other.significant
    # Smallest case: [3] vs [1, 2] has U = 2 of 2, exact p = 1 / 3.
    assert es.mann_whitney([3.0], [1.0, 2.0], "greater").p == pytest.approx(1 / 3)
    assert es.mann_whitney([3.0], [1.0, 2.0], "less").p == pytest.approx(1.0)


def test_mann_whitney_ties_normal_approximation_by_hand():
    """Success rates tie often: scipy falls back to the normal approximation, tie-corrected."""
    x, y = [100.0, 100.0, 98.0, 96.0, 96.0], [98.0, 96.0, 94.0, 94.0]
    # U_x: 100 beats all 4 (x2) = 8; 98 beats 96, 94, 94 and ties 98 = 3.5; each 96 beats
    # 94, 94 and ties 96 = 2.5 (x2) -> U = 16.5.
    u = 8 + 3.5 + 2 * 2.5
    n1, n2 = len(x), len(y)
    n = n1 + n2
    ties = [2, 2, 3, 2]  # 100 x2, 98 x2, 96 x3, 94 x2
    sigma = math.sqrt(n1 * n2 / 12 * ((n + 1) - sum(t**3 - t for t in ties) / (n * (n - 1))))
    z = (u - n1 * n2 / 2 - 0.5) / sigma  # continuity correction
    p = 0.5 * math.erfc(z / math.sqrt(2))
    test = es.mann_whitney(x, y, "greater")
    assert test.u == u
    assert test.p == pytest.approx(p, rel=1e-10)
    # Identical samples: nothing to conclude; empty samples: NaN, never an exception.
    assert es.mann_whitney([100.0] * 3, [100.0] * 4, "greater").p == pytest.approx(1.0)
    assert math.isnan(es.mann_whitney([], [1.0], "greater").p)
    assert math.isnan(es.mann_whitney([np.nan], [1.0], "less").p)


def test_quarter_order_and_comparison_tests():
    grid = synthetic_grid()
    tests = {
        (t.first, t.second): t
        for t in es.quarter_order_tests(grid.success_pct, grid.quarter, "success")
    }
    assert set(tests) == set(es.QUARTER_PAIRS) and len(tests) == 6
    assert tests[("Q1", "Q4")].better.p == pytest.approx(2 / 70)
    assert tests[("Q1", "Q4")].conclusion() == ("Q1", "Q4")
    assert tests[("Q3", "Q4")].conclusion() is None
    # Time: better means shorter. Q1 times are all below Q4's: U = 0, p = 1 / 70 for "less".
    times = {
        (t.first, t.second): t
        for t in es.quarter_order_tests(grid.time_mean_s, grid.quarter, "time")
    }
    assert times[("Q1", "Q4")].better.u == 0.0
    assert times[("Q1", "Q4")].better.p == pytest.approx(1 / 70)
    assert times[("Q1", "Q4")].conclusion() == ("Q1", "Q4")
    # Against another grid: every success rate 10 points lower -> "less" in every quarter.
    worse = grid_table.GridTable(**{**synthetic_grid().__dict__, "successes": grid.successes - 10})
    result = es.compare_quarters(
        worse.success_pct, worse.quarter, grid.success_pct, grid.quarter, "less"
    )
    assert set(result) == set(es.QUARTERS)
    # Q1 [90, 88, 86, 84] vs [100, 98, 96, 94]: U = 0 -> p = 1 / 70.
    assert result["Q1"].u == 0.0 and result["Q1"].p == pytest.approx(1 / 70)


def _tex_rows(text: str, label: str) -> list[list[float]]:
    rows = re.findall(r"\\textbf\{" + label + r"\}\s*((?:&\s*[0-9.]+\s*){4})", text)
    return [[float(v) for v in re.findall(r"[0-9.]+", r)] for r in rows]


def test_paper_numbers_match_tables_4_and_5():
    nominal = PAPER["nominal"]
    assert nominal.success.mean == (96.96, 94.22, 91.83, 87.83)
    assert nominal.time.mean == (1.9, 2.72, 4.34, 4.88)
    assert nominal.success_order == {
        ("Q1", "Q2"),
        ("Q1", "Q3"),
        ("Q1", "Q4"),
        ("Q2", "Q3"),
        ("Q2", "Q4"),
        ("Q3", "Q4"),
    }
    assert paper_order_conclusion(PAPER["25mm"].success_order, "Q2", "Q3") == "Q3 better"
    assert paper_order_conclusion(PAPER["25mm"].success_order, "Q1", "Q3") == "n.s."
    if not PAPER_TEX.is_file():
        pytest.skip(f"{PAPER_TEX} not available")
    text = PAPER_TEX.read_text()
    split = text.index(r"\label{tab:summary results time}")
    success_conditions = ["nominal", "60mm", "25mm", "triangle", "transfer"]
    time_conditions = ["nominal", "60mm", "25mm", "transfer"]
    for part, conditions, metric in (
        (text[:split], success_conditions, "success"),
        (text[split:], time_conditions, "time"),
    ):
        for stat in ("mean", "min", "max"):
            rows = _tex_rows(part, stat)
            assert len(rows) == len(conditions), (metric, stat, rows)
            for name, row in zip(conditions, rows, strict=True):
                ours = getattr(getattr(PAPER[name], metric), stat)
                assert list(ours) == row, (name, metric, stat)


def test_grid_csv_round_trip_and_summary(tmp_path):
    grid = synthetic_grid()
    path = tmp_path / "grid.csv"
    path.write_text(grid.csv_text())
    header = path.read_text().splitlines()[0].split(",")
    assert header == list(grid_table.GRID_COLUMNS)
    back = grid_table.GridTable.from_csv(path)
    np.testing.assert_array_equal(back.successes, grid.successes)
    np.testing.assert_allclose(back.time_mean_s, grid.time_mean_s)
    np.testing.assert_array_equal(back.quarter, grid.quarter)
    text = summary.summary_markdown(grid, ["policy: test"], "nominal", back, "other", "less")
    assert "97.00 (96.96)" in text  # Q1 mean success beside the paper's
    assert "89.25 (87.83)" in text
    assert "| Q1 vs Q4 | success | 15.0 | 0.0286 |" in text
    assert "## Against other" in text
    with pytest.raises(ValueError, match="not an evaluation grid.csv"):
        (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
        grid_table.GridTable.from_csv(tmp_path / "bad.csv")


def test_heatmaps_are_written(tmp_path):
    grid = synthetic_grid()
    matrix, linear, angular = grid_matrix(grid, grid.success_pct)
    assert matrix.shape == (4, 4) and list(linear) == [1, 2, 3, 4]
    assert matrix[0, 0] == 100.0  # bottom left = smallest errors = Q1
    t = grid.time_mean_s.copy()
    t[0] = np.nan  # a range without a success
    grid = grid_table.GridTable(**{**grid.__dict__, "time_mean_s": t})
    for fn, name in ((success_heatmap, "s.png"), (time_heatmap, "t.png")):
        path = fn(grid, tmp_path / name)
        data = path.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    means, mins, maxes = quarter_stats_by_metric(grid)["success"]
    assert means[0] == pytest.approx(97.0) and mins[0] <= means[0] <= maxes[0]
    for condition in ("nominal", "triangle"):  # the triangle has no paper times: one panel
        path = paper_bars(grid, PAPER[condition], tmp_path / f"{condition}.png", condition)
        data = path.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000


def test_parse_ranges():
    assert cli.parse_ranges("0.5, 1,2", "--linear-mm") == (0.5, 1.0, 2.0)
    assert cli.parse_ranges("1:3:1,4.5", "--linear-mm") == (1.0, 2.0, 3.0, 4.5)
    assert len(cli.parse_ranges("0.32:8:0.32", "--linear-mm")) == 25
    for bad in ("", " , ", "3:1:1"):
        with pytest.raises(ValueError, match="--linear-mm is empty"):
            cli.parse_ranges(bad, "--linear-mm")
    with pytest.raises(ValueError, match="cannot read"):
        cli.parse_ranges("1,x", "--linear-mm")


def test_range_specs_depend_only_on_seed_and_index():
    config = eval_config.EvalConfig(
        "baseline", "custom", (1.0, 4.0), (2.0,), 5, ("circle", "square"), 50.0, 1.0, seed=3
    )
    assert config.shape_counts() == [3, 2]
    a, b = eval_config.range_specs(config, 1), eval_config.range_specs(config, 1)
    np.testing.assert_array_equal(a.loc_error, b.loc_error)
    assert list(a.shape_id) == [0, 0, 0, 1, 1]
    assert np.all(np.abs(a.loc_error[:, :2]) <= 0.004) and np.all(a.linear_range == 0.004)
    other_seed = eval_config.range_specs(config.__class__(**{**config.__dict__, "seed": 4}), 1)
    assert not np.allclose(a.board_pos, other_seed.board_pos)
    # Preset linear ranges scale with S (percent of S/2 in the paper) unless asked not to.
    assert eval_config.grid_axes("paper-small", 25.0)[0][-1] == pytest.approx(4.0)
    assert eval_config.grid_axes("paper-small", 25.0, linear_absolute=True)[0][-1] == 8.0


TINY = [
    "--policy", "baseline", "--grid", "custom", "--linear-mm", "0.5,3", "--angular-deg", "1,6",
    "--trials", "4", "--time-limit", "2", "--shape", "circle,square", "--engine", "mujoco",
    "--seed", "7", "--chunk-trials", "4", "--no-progress",
]  # fmt: skip


def test_resume_after_interruption_gives_the_same_grid(tmp_path, monkeypatch, capsys):
    import multiprocessing

    full, resumed = tmp_path / "full", tmp_path / "resumed"
    assert eval_cli.main([*TINY, "--out", str(full)]) == 0
    assert not multiprocessing.active_children()  # its worker processes stopped with it
    for name in ("grid.csv", "summary.md", "success_heatmap.png", "time_heatmap.png"):
        assert (full / name).stat().st_size > 0, name
    assert (full / "paper_comparison.png").stat().st_size > 0  # circle + square, 50 mm: nominal
    rows = (full / "grid.csv").read_text().splitlines()
    assert len(rows) == 5 and rows[1].startswith("0,0.5,1,Q1,4,")

    real = runner.run_trials
    calls = []

    def interrupted(specs, *args, **kwargs):
        calls.append(len(specs))
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(specs, *args, **kwargs)

    monkeypatch.setattr(runner, "run_trials", interrupted)
    assert eval_cli.main([*TINY, "--out", str(resumed)]) == 130
    assert "2 of 4 ranges saved" in capsys.readouterr().err
    assert not (resumed / "grid.csv").exists()
    assert len(list((resumed / "ranges").glob("*.npz"))) == 2

    calls.clear()
    monkeypatch.setattr(runner, "run_trials", lambda *a, **k: calls.append(1) or real(*a, **k))
    assert eval_cli.main([*TINY, "--out", str(resumed)]) == 0
    assert len(calls) == 2  # only the two unfinished ranges ran
    assert (resumed / "grid.csv").read_bytes() == (full / "grid.csv").read_bytes()
    # All four ranges in one engine call: the same results (chunking changes nothing).
    one_call = tmp_path / "one_call"
    assert eval_cli.main([*TINY, "--chunk-trials", "1000", "--out", str(one_call)]) == 0
    assert (one_call / "grid.csv").read_bytes() == (full / "grid.csv").read_bytes()

    # A finished evaluation reruns nothing; --compare tests it against another.
    calls.clear()
    argv = [*TINY, "--out", str(resumed), "--compare", str(full), "--alternative", "greater"]
    assert eval_cli.main(argv) == 0 and not calls
    summary = (resumed / "summary.md").read_text()
    assert f"## Against {full}" in summary and "after-vs-before" in summary

    # Resuming with another config is refused with one line.
    capsys.readouterr()
    assert eval_cli.main([*TINY[:-1], "--no-progress", "--seed", "8", "--out", str(full)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("eval.py: error:") and "seed: 7 there, 8 now" in err
    assert len(err.splitlines()) == 1


def test_learned_policy_directory(tmp_path):
    from mjx_peg.policy.export import save_policy

    rng = np.random.default_rng(0)
    run = tmp_path / "run"
    layers = [
        (0.1 * rng.normal(size=(8, 16)), np.zeros(16)),
        (0.1 * rng.normal(size=(16, 38)), np.zeros(38)),
    ]
    save_policy(run, layers=layers, obs_mean=np.zeros(8), obs_std=np.ones(8), config={})
    out = tmp_path / "eval"
    argv = [
        "--policy", str(run), "--grid", "custom", "--linear-mm", "1", "--angular-deg", "1",
        "--trials", "2", "--time-limit", "0.5", "--shape", "square", "--engine", "mujoco",
        "--no-progress", "--out", str(out),
    ]  # fmt: skip
    assert eval_cli.main(argv) == 0
    import json

    config = json.loads((out / "config.json").read_text())
    assert config["config"]["policy"].startswith("sha256:")
    assert config["policy_dir"] == str(run.resolve())
    assert (out / "grid.csv").read_text().count("\n") == 2
    # a shipped policy is recorded by its name, which every checkout resolves
    argv[argv.index(str(run))], argv[-1] = "paper", str(tmp_path / "eval_shipped")
    assert eval_cli.main(argv) == 0
    shipped = json.loads((tmp_path / "eval_shipped" / "config.json").read_text())
    assert shipped["policy_dir"] == "paper"


def test_the_skill_is_the_policys_unless_given_and_old_evaluations_read_as_they_ran(tmp_path):
    """Without --skill an evaluation runs the skill the policy's manifest names (a manifest
    without one: the skill it was trained with, here `search` of an earlier version, its
    constants as they were); config.json records the name and every constant. Evaluations
    written before constants were recorded read as the named skill's (`search`, `align`: as
    they were; none named: the paper's) and resume."""
    import json

    from mjx_peg.file_versions import FORMER_SKILLS
    from mjx_peg.policy.export import save_policy
    from mjx_peg.skill.search import SKILLS, NamedSkill, SkillConfig, constants_record

    run = tmp_path / "run"
    layers = [(np.zeros((8, 38)), np.zeros(38))]
    save_policy(run, layers=layers, obs_mean=np.zeros(8), obs_std=np.ones(8),
                config={"skill": "search"})  # fmt: skip
    manifest = json.loads((run / "manifest.json").read_text())
    del manifest["skill"]  # written before manifests named the skill to run them with
    (run / "manifest.json").write_text(json.dumps(manifest))
    argv = [
        "--policy", str(run), "--grid", "custom", "--linear-mm", "1", "--angular-deg", "1",
        "--trials", "1", "--time-limit", "0.2", "--shape", "square", "--engine", "mujoco",
        "--no-progress",
    ]  # fmt: skip
    search = SkillConfig(centre_gain=1.0)  # the centring alone
    runs = (([], "search", search), (["--skill", "spiral"], "spiral", SKILLS["spiral"]))
    for extra, skill, constants in runs:
        out = tmp_path / f"eval_{skill}"
        assert eval_cli.main([*argv, *extra, "--out", str(out)]) == 0
        recorded = json.loads((out / "config.json").read_text())["config"]
        assert recorded["skill"] == skill
        assert recorded["skill_constants"] == constants_record(constants)
        assert len(recorded["skill_constants"]) == len(SkillConfig.__dataclass_fields__)
        assert f"skill: {skill} (" in (out / "summary.md").read_text()
    assert SkillConfig(**FORMER_SKILLS["search"]) == search
    # An evaluation of an earlier version: no constants, or no skill at all.
    for name, expected in (("align", search.replace(align_rate=1.0)), (None, SKILLS["paper"])):
        doc = json.loads((out / "config.json").read_text())
        doc["config"].pop("skill_constants", None)
        if name is None:
            del doc["config"]["skill"]  # written before the contact search
        else:
            doc["config"]["skill"] = name
        (out / "config.json").write_text(json.dumps(doc))
        config, _ = eval_dir.read_eval_dir(out)
        assert config.skill == (name or "paper") and config.trial_config().search == expected
        assert eval_dir.prepare_out_dir(out, config) == out  # resumed as it is
    assert policy_skill("baseline") == NamedSkill("paper", SKILLS["paper"])


def test_a_rerun_whose_skill_constants_changed_is_refused(tmp_path, monkeypatch, capsys):
    """The skill's constants are part of the evaluation's config: after one constant of the
    spiral changed, the same command refuses in one line naming --out and the constant, and
    runs and writes nothing (no old ranges resumed beside new ones)."""
    from mjx_peg.skill import search

    out = tmp_path / "spiral"
    argv = [*TINY, "--linear-mm", "1", "--angular-deg", "1", "--skill", "spiral", "--out",
            str(out)]  # fmt: skip
    assert eval_cli.main(argv) == 0
    before = {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    changed = search.SKILLS["spiral"].replace(spiral_speed=0.04)
    monkeypatch.setitem(search.SKILLS, "spiral", changed)
    calls = []
    monkeypatch.setattr(runner, "run_trials", lambda *a, **k: calls.append(1))
    capsys.readouterr()
    assert eval_cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"--out {out}" in err
    assert "skill_constants.spiral_speed: 0.03 there, 0.04 now" in err
    assert not calls
    assert {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()} == before


@pytest.mark.parametrize(
    "change, message",
    [
        ({"--policy": "EMPTY_DIR"}, "holds no policy.npz"),
        ({"--linear-mm": ""}, "--linear-mm is empty"),
        ({"--angular-deg": "5:1:1"}, "--angular-deg is empty"),
        ({"--trials": "-3"}, "--trials must be an integer in 1..100,000, got -3"),
        ({"--shape": "hexagon"}, "unknown shape 'hexagon'"),
        ({"--linear-mm": "80"}, "--linear-mm ranges must lie in [0, 50] mm, got 80"),
        ({"--compare": "NO_DIR"}, "nope does not exist"),
    ],
)
def test_bad_input_is_one_clear_line(tmp_path, capsys, change, message):
    (tmp_path / "empty").mkdir()
    argv = [*TINY, "--out", str(tmp_path / "out")]
    for key, value in change.items():
        value = {"EMPTY_DIR": str(tmp_path / "empty"), "NO_DIR": str(tmp_path / "nope")}.get(
            value, value
        )
        if key in argv:
            argv[argv.index(key) + 1] = value
        else:
            argv += [key, value]
    assert eval_cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("eval.py: error:") and message in err, err
    assert not (tmp_path / "out" / "ranges").exists()


def test_cli_script(tmp_path):
    """`python eval.py`: --help works; bad input exits non-zero with one line, no traceback."""
    run = subprocess.run(
        [sys.executable, "eval.py", "--help"], cwd=REPO, capture_output=True, text=True
    )
    assert run.returncode == 0 and "--grid" in run.stdout and "--compare" in run.stdout
    run = subprocess.run(
        [sys.executable, "eval.py", "--policy", str(tmp_path), "--out", str(tmp_path / "o")],
        cwd=REPO,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        f"eval.py: error: {tmp_path} holds no policy.npz: not a run directory with a policy"
    ]


def test_evaluations_from_before_early_ending_read_as_full_time_limit(tmp_path, capsys):
    """A config.json without full_time_limit (written before early ending) ran every failure to
    the time limit: it reads so, and resuming it needs --full-time-limit."""
    import json

    out = tmp_path / "old"
    assert eval_cli.main([*TINY, "--full-time-limit", "--out", str(out)]) == 0
    assert "every failure ran to the time limit" in (out / "summary.md").read_text()
    doc = json.loads((out / "config.json").read_text())
    del doc["config"]["full_time_limit"]
    (out / "config.json").write_text(json.dumps(doc))
    config, _ = eval_dir.read_eval_dir(out)
    assert config.full_time_limit and not config.trial_config().end_settled
    assert eval_cli.main([*TINY, "--full-time-limit", "--out", str(out)]) == 0
    capsys.readouterr()
    assert eval_cli.main([*TINY, "--out", str(out)]) == 2
    assert "full_time_limit: True there, False now" in capsys.readouterr().err


def test_evaluations_from_before_credible_contact_are_read_but_not_resumed(tmp_path, capsys):
    """A config.json without contact_model (written before the F/T pipeline and the protective
    stop) ran another trial: its ranges still load (without contact metrics) and grid.csv has
    no contact values, but it is neither resumed nor replayed."""
    import json

    from mjx_peg.evaluation import demo_cli

    out = tmp_path / "old"
    assert eval_cli.main([*TINY, "--out", str(out)]) == 0
    grid = (out / "grid.csv").read_text().splitlines()
    assert grid[0].endswith("settled,protective_stops,peak_force_median_n,chatter_under_5n_pct")
    assert "nan" not in grid[1].split(",")[-3]  # the peak force of the current trial
    assert "contact: peak sensed force median" in (out / "summary.md").read_text()
    doc = json.loads((out / "config.json").read_text())
    del doc["config"]["contact_model"]
    (out / "config.json").write_text(json.dumps(doc))
    for path in (out / "ranges").iterdir():
        with np.load(path) as npz:
            arrays = {k: npz[k] for k in npz.files if k not in ("chatter", "protective_stop")}
        np.savez(path, **arrays)
    config, _ = eval_dir.read_eval_dir(out)
    assert config.contact_model == 1
    assert eval_dir.grid_table(out, config).peak_force_median_n is not None
    assert np.isnan(eval_dir.grid_table(out, config).protective_stops).all()
    capsys.readouterr()
    assert eval_cli.main([*TINY, "--out", str(out)]) == 2
    assert "contact_model: 1 there, 2 now" in capsys.readouterr().err
    argv = ["--replay", str(out), "--range", "0", "--trial", "0", "--out", str(tmp_path / "d")]
    assert demo_cli.main(argv) == 2
    assert "before credible contact" in capsys.readouterr().err
