"""Each script under experiments/ (and benchmarks/trials.py's profile) runs with tiny arguments,
so that none can rot."""

import csv
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def run(path: str, *args) -> subprocess.CompletedProcess:
    """`python ROOT/path args`, its output captured, whatever its exit status."""
    return subprocess.run([sys.executable, ROOT / path, *map(str, args)], capture_output=True,
                          text=True, cwd=ROOT)  # fmt: skip


def run_script(path: str, *args) -> str:
    """stdout of `python ROOT/path args` (it must exit 0)."""
    done = run(path, *args)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def test_fingerprint_runs_and_compares_bit_for_bit(tmp_path):
    script = ROOT / "experiments" / "fingerprint.py"
    first, second = tmp_path / "a.npz", tmp_path / "b.npz"
    tiny = ["--trials", "3", "--time-scale", "0.02"]
    done = subprocess.run([sys.executable, script, first, *tiny], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    done = subprocess.run([sys.executable, script, second, *tiny, "--compare", first],
                          capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert "80 of 80 arrays bit-identical" in done.stdout


def test_contact_writes_a_row_per_trial_and_contact_table_pairs_two_runs(tmp_path):
    tiny = ["--trials", 3, "--time-limit", 0.3, "--threads", 1, "--shapes", "square"]
    nominal, nofilter = tmp_path / "nominal.csv", tmp_path / "nofilter.csv"
    out = run_script("experiments/contact.py", *tiny, "--csv", nominal)
    assert "3 trials" in out and "physics steps" in out
    out = run_script("experiments/contact.py", *tiny, "--sensor", "nofilter", "--friction", 0.2,
                     "--policy", "quick", "--csv", nofilter)  # fmt: skip
    assert "policy quick, skill spiral" in out and "friction 0.2," in out  # the policy's skill
    with open(nominal) as f:
        rows = list(csv.DictReader(f))
    assert [int(r["trial"]) for r in rows] == [0, 1, 2]
    assert {"success", "peak_force", "chatter", "tip_depth_mm", "tip_off_axis_mm"} <= set(rows[0])
    assert all(int(r["steps"]) == 150 and float(r["time_s"]) == 0.3 for r in rows)  # 2 ms steps
    assert all(0.0 < float(r["peak_force"]) < 150.0 for r in rows)
    table = run_script("experiments/contact_table.py", "--reference", nominal, nominal, nofilter)
    lines = table.strip().splitlines()
    assert len(lines) == 4 and lines[0].startswith("| run | success")
    assert lines[2].startswith("| nominal | 0.0 % (0 / 3)") and "0 lost, 0 gained" in lines[2]
    assert lines[3].startswith("| nofilter |")
    # --indices: those trials only, the CSV keeping their numbers
    (tmp_path / "indices.txt").write_text("2\n0\n")
    some = tmp_path / "some.csv"
    out = run_script("experiments/contact.py", *tiny, "--indices", tmp_path / "indices.txt",
                     "--csv", some)  # fmt: skip
    assert "2 trials of 3" in out
    with open(some) as f:
        picked = list(csv.DictReader(f))
    assert [int(r["trial"]) for r in picked] == [2, 0]
    assert [r["tip_off_axis_mm"] for r in picked] == [rows[2]["tip_off_axis_mm"],
                                                      rows[0]["tip_off_axis_mm"]]  # fmt: skip


def test_early_ending_pairs_two_evaluations_and_writes_its_section(tmp_path):
    from mjx_peg.evaluation.config import EvalConfig
    from mjx_peg.evaluation.eval_dir import prepare_out_dir
    from mjx_peg.evaluation.runner import load_controller, run_evaluation

    dirs = {}
    for full in (False, True):
        config = EvalConfig(policy="baseline", grid="custom", linear_mm=(1.0,),
                            angular_deg=(1.0, 2.0), trials=2, shapes=("square",),
                            size_mm=50.0, time_limit_s=0.3, full_time_limit=full)  # fmt: skip
        out = dirs[full] = tmp_path / ("full" if full else "early")
        prepare_out_dir(out, config, None)
        _, controller = load_controller("baseline")
        assert run_evaluation(config, out, controller, {"threads": 1}, show_progress=False)
    report = tmp_path / "BENCHMARKS.md"
    report.write_text("# Benchmarks\n\n## Early ending\n\nold\n\n## Next\n\nkept\n")
    out = run_script("experiments/early_ending.py", dirs[False], dirs[True], "--write", report)
    assert "Same outcome: 4 of 4 trials (100.00 %)" in out
    text = report.read_text()
    assert "old" not in text and "Same outcome: 4 of 4" in text and "## Next\n\nkept" in text
    assert "Reproduce: `python experiments/early_ending.py" in text


def test_withdrawn_ending_reruns_an_evaluations_failures_and_pairs_two_runs(tmp_path):
    from mjx_peg.evaluation.config import EvalConfig
    from mjx_peg.evaluation.eval_dir import prepare_out_dir
    from mjx_peg.evaluation.runner import load_controller, run_evaluation

    config = EvalConfig(policy="baseline", grid="custom", linear_mm=(1.0,), angular_deg=(1.0,),
                        trials=2, shapes=("square",), size_mm=50.0, time_limit_s=0.2,
                        skill="spiral")  # fmt: skip
    prepare_out_dir(tmp_path / "eval", config, None)
    _, controller = load_controller("baseline")
    assert run_evaluation(config, tmp_path / "eval", controller, {"threads": 1},
                          show_progress=False)  # fmt: skip
    args = ("--eval", tmp_path / "eval", "--policy", "baseline", "--pass", "numpy")
    out = run_script("experiments/withdrawn_ending.py", tmp_path / "a.npz", *args)
    assert "2 trials of " in out and "0 succeeded" in out  # 0.2 s: both ran to the limit
    out = run_script("experiments/withdrawn_ending.py", tmp_path / "b.npz", *args, "--compare",
                     tmp_path / "a.npz")  # fmt: skip
    assert "outcome differs on 0 of 2 [], class on 0 []; steps on 0 (0 successes)" in out
    with np.load(tmp_path / "b.npz") as saved:
        assert saved["picked"].tolist() == [[0, 0], [0, 1]] and saved["steps"].tolist() == [100] * 2


def test_replay_failure_finds_a_failure_and_plots_its_replay(tmp_path):
    png = tmp_path / "replay.png"
    out = run_script("experiments/replay_failure.py", "--policy", "baseline", "--old-policy",
                     "baseline", "--out", png, "--trials", 2, "--search-time-limit", 0.1,
                     "--confirm-time-limit", 0.2, "--time-limit", 0.2)  # fmt: skip
    assert "2 trials: first failure of baseline under the old trial (0.1 s) is trial 0" in out
    assert "under the current trial, baseline: 0/1 succeeded" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_trials_benchmark_prints_its_table_and_the_profile(tmp_path):
    out = run_script("benchmarks/trials.py", "--trials", 4, "--time-limit", 0.2, "--threads", 1,
                     "--repeat", 1, "--mjx-trials", 0, "--replay-every", 25)  # fmt: skip
    assert "| bare mj_step (ceiling) |" in out and "| bare `Batch.step` |" in out
    for name in ("numpy", "compiled"):
        assert f"| mujoco, {name} pass, lanes as threads | " in out
        assert f"profile of one lane (threads=1), {name} pass, µs per env-step:" in out
    from mjx_peg.engines.lanes import PROFILE_STAGES

    for stage in PROFILE_STAGES:
        assert f"  {stage}: " in out
    assert "100 control periods, 4.0 trials each on average" in out  # 0.2 s, 4 slots
    # the share of physics from the one run and the Batch.step run timed just before it
    assert re.search(r"\*\*(\d+) %\*\* of `Batch.step` \(pairs: \1 %\)", out)
    # the reference steps the engine's own trajectory: each window replayed with the engine's
    # torques ends on the engine's next snapshot, bit for bit
    windows = re.search(r"next snapshot bit for bit in (\d+) of (\d+) windows", out)
    assert windows and windows[1] == windows[2] and int(windows[2]) >= 8


def test_the_layouts_benchmark_profiles_each_layout_and_the_batch_by_memory_touched():
    out = run_script("benchmarks/layouts.py", "--trials", 4, "--layouts", "1x4,2x2/2",
                     "--repeat", 1, "--sims", 4, "--touch-mb", "0,1")  # fmt: skip
    for layout in ("1x4", "2x2/2"):
        line = re.search(rf"run 1, {re.escape(layout)}: ([\d,]+) steps/s .*lane-µs per env-step: "
                         r"(.*)", out)  # fmt: skip
        assert line, out
        assert int(line[1].replace(",", "")) > 0
        assert "step " in line[2] and "advance " in line[2] and "idle and the rest " in line[2]
    assert re.search(r"run 1, 4 simulations: 0 MB \d+\.\d+ 1 MB \d+\.\d+", out)


def test_the_profile_hook_sees_every_stage_and_changes_no_result():
    from mjx_peg.engines import mujoco as engine
    from mjx_peg.engines.lanes import PROFILE_STAGES
    from mjx_peg.engines.trial import TrialConfig, as_controller_params
    from mjx_peg.skill.baseline import baseline_params
    from mjx_peg.world.task import TaskConfig, sample_trials

    task = TaskConfig(shapes=("circle", "square"), linear_error=0.004, angular_error=0.1)
    specs = sample_trials(task, 5, 5)
    params = as_controller_params(baseline_params(), len(specs))
    config = TrialConfig(time_limit_s=0.2)
    seconds, calls = {}, {}

    def profile(stage, s):
        assert s >= 0.0
        seconds[stage] = seconds.get(stage, 0.0) + s
        calls[stage] = calls.get(stage, 0) + 1

    plain = engine.run_on_cpu(specs, params, config, threads=1, slots_per_thread=2)
    watch = lambda lane, rows, wrench: None  # noqa: E731  (the observer stage too)
    timed = engine.run_on_cpu(specs, params, config, threads=1, slots_per_thread=2,
                              profile=profile, observer=watch)  # fmt: skip
    for name, value in plain.to_arrays().items():
        assert value.tobytes() == timed.to_arrays()[name].tobytes(), name
    assert set(calls) == set(PROFILE_STAGES)
    assert (timed.steps == 100).all()  # 0.2 s each: on 2 slots, 3 rounds of 100 periods
    assert calls["step"] == calls["advance"] == calls["observer"] == 300
    with pytest.raises(ValueError, match="profile"):
        engine.run_on_cpu(specs, params, config, processes=1, profile=profile)


# experiments/engines_agree.py runs in tests/engines/test_mjx.py::test_engines_agree (one
# MJX compile for the agreement check and the script's smoke test).


@pytest.mark.slow
def test_contact_diff_shows_both_engines_contacts_of_one_state():
    text = run_script("experiments/contact_diff.py", "--trials", 6, "--count", 1, "--step", 10,
                      "--time-limit", 0.05, "--shape", "square")  # fmt: skip
    assert "trial 3 (square) at step 10:" in text
    assert "  mujoco: " in text and "  mjx: " in text and "qacc: mujoco" in text


def test_failures_classifies_each_failed_trial(tmp_path):
    out = tmp_path / "f.npz"
    text = run_script("experiments/failures.py", "--shape", "square", "--trials", 3,
                      "--time-limit", 0.3, "--list", "--out", out)  # fmt: skip
    assert "## square: 0/3 succeeded" in text  # 0.3 s: still above the board
    assert "3 of 3 trials failed" in text and "| above the board | 3 | 100.0 | 3 |" in text
    assert len(re.findall(r"trial +\d+: above the board +tip", text)) == 3  # one per failure
    with np.load(out) as saved:
        assert saved["square/result/final_tip_pos"].shape == (3, 3)
        assert saved["square/spec/board_tilt"].shape == (3, 2)


def test_grid_subset_runs_an_evaluations_own_trials_per_quarter(tmp_path):
    out = run_script("experiments/grid_subset.py", "--per-shape", 1, "--time-limit", 0.3,
                     "--threads", 1, "--npz", tmp_path / "s.npz")  # fmt: skip
    assert "200 trials of docs/eval/paper_spiral_50mm_small_board" in out
    assert all(f"Q{q} " in out for q in range(1, 5))
    saved = np.load(tmp_path / "s.npz")
    assert saved["range"].tolist() == [r for r in range(100) for _ in range(2)]
    assert not saved["success"].any()  # 0.3 s: still above the board


def test_chatter_trace_replays_a_grid_trial_and_reports_its_last_second(tmp_path):
    out = run_script("experiments/chatter_trace.py", "--eval",
                     "docs/eval/paper_spiral_50mm_small_board", "--range", 0, "--trial", 0,
                     "--contacts-at", 0.7, "--search", "search_budget=inf",
                     "--npz", tmp_path / "t.npz")  # fmt: skip
    assert "range 0 (±0.8 mm / ±1.2 deg) trial 0" in out and "recorded: success" in out
    assert "search constants: search_budget=inf" in out
    assert "chatter (mean |dF|)" in out and "the compliance's axial force" in out
    assert len(re.findall(r"^  0\.\d{3} s  axial", out, flags=re.M)) == 40  # the contacts listed
    with np.load(tmp_path / "t.npz") as trace:
        assert trace["tcp"].shape == (trace["axial"].size, 3) and trace["axial"].size > 100


def test_regenerate_lists_every_step_and_runs_and_resumes_the_chosen(tmp_path):
    listed = run_script("experiments/regenerate.py", "--dry-run", "--out", tmp_path).splitlines()
    names = [line.split(":")[0] for line in listed[:-1]]
    assert names[:2] == ["train_quick", "ship_quick"]  # shipped before anything runs `quick`
    assert names.index("skill_paper") < names.index("g_paper_spiral_50mm_small_board")
    assert names.index("skill_family") < names.index("g_family_spiral_50mm_small_board")
    # the longest last, the family's compared with the paper's
    assert names[-2:] == ["g_paper_spiral_50mm_nominal_board", "g_family_spiral_50mm_nominal_board"]
    assert len(names) == len(set(names)) == 49
    compared = names.index("g_transfer_spiral_triangle_small_board")
    assert names.index("g_paper_spiral_triangle_small_board") < compared
    assert re.fullmatch(r"49 steps, ~\d+ min here", listed[-1])
    only = run_script("experiments/regenerate.py", "--dry-run", "--only", "arm_*_125")
    assert [line.split(":")[0] for line in only.splitlines()[:-1]] == [
        "arm_circle_125", "arm_square_125"]  # fmt: skip
    # one real step (zero error: 180 trials, ~6 s on two cores), then the rerun skips it
    results = ("--results", tmp_path / "results")  # not the shipped docs/results
    out = run_script("experiments/regenerate.py", "--only", "zero", "--out", tmp_path, *results)
    assert "[1/1] zero" in out and "done in" in out
    assert "60/60 succeeded" in (tmp_path / "zero.log").read_text()
    assert (tmp_path / "results" / "zero_error.npz").is_file()
    again = run_script("experiments/regenerate.py", "--only", "zero", "--out", tmp_path, *results)
    assert "zero: done before, skipped" in again and "[1/" not in again
    redone = run_script("experiments/regenerate.py", "--only", "zero", "--redo", "zero",
                        "--out", tmp_path, *results)  # fmt: skip
    assert "[1/1] zero" in redone and "done before" not in redone
    assert (tmp_path / "zero.done").is_file()
    stray = run("experiments/regenerate.py", "--only", "zero", "--redo", "g_*", "--out", tmp_path)
    assert stray.returncode == 2 and stray.stderr.strip() == "--redo g_*: no chosen step matches"
    bad = run("experiments/regenerate.py", "--only", "nope")
    assert bad.returncode == 2 and bad.stderr.strip() == "--only nope: no step matches"
    (tmp_path / "commit").write_text("0" * 40 + "\n")  # a regeneration of another commit
    other = run("experiments/regenerate.py", "--only", "zero", "--out", tmp_path)
    assert other.returncode == 2 and "holds a regeneration of commit 0000000" in other.stderr


def test_the_regenerations_eta_takes_the_pace_only_of_enough_steps(monkeypatch):
    """A 1 s step expected at 5 s does not make 40 minutes left read 8; ten minutes of steps at
    twice their expected time make it 80."""
    monkeypatch.syspath_prepend(str(ROOT / "experiments"))
    from regenerate import left_s

    assert left_s(2400.0, 1.0, 5.0) == 2400.0
    assert left_s(2400.0, 1200.0, 600.0) == 4800.0
    assert left_s(2400.0, 0.0, 0.0) == 2400.0


def test_ship_policy_records_the_skill_a_shipped_policy_runs(tmp_path, monkeypatch, paper_38):
    """`ship_policy.record_skill` on a copy of the `paper` shipped until 2026-12 (trained with
    the `search` skill) as written before skills were recorded: by default it runs the skill it
    trained with (`search`, as it was); with --skill spiral its manifest and config.json are the
    ones it was shipped with, byte for byte, and its policy.npz is untouched; a constant given
    (`--skill-constant`) is set on the skill it runs, not on the one it trained with."""
    import json
    import shutil

    from mjx_peg.policy.export import load_policy
    from mjx_peg.skill.search import SKILLS, NamedSkill, SkillConfig

    monkeypatch.syspath_prepend(str(ROOT / "experiments"))
    import ship_policy

    shipped, copy = paper_38, tmp_path / "paper"
    shutil.copytree(shipped, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    del manifest["skill"], manifest["config"]["skill_constants"]
    (copy / "manifest.json").write_text(json.dumps(manifest))
    config = json.loads((copy / "config.json").read_text())
    del config["skill_constants"]
    (copy / "config.json").write_text(json.dumps(config))
    assert load_policy(copy).skill == NamedSkill("search", SkillConfig(centre_gain=1.0))
    assert ship_policy.record_skill(copy, None) == "search"
    assert load_policy(copy).skill == NamedSkill("search", SkillConfig(centre_gain=1.0))
    assert ship_policy.record_skill(copy, "spiral") == "spiral"
    assert load_policy(copy).skill == NamedSkill("spiral", SKILLS["spiral"])
    for name in ("manifest.json", "config.json", "policy.npz"):
        assert (copy / name).read_bytes() == (shipped / name).read_bytes(), name
    trained = load_policy(copy).trained_skill
    assert ship_policy.record_skill(copy, "spiral", [("yaw_scale", "uncertainty")]) == "spiral"
    widened = SKILLS["spiral"].replace(yaw_scale="uncertainty")
    assert load_policy(copy).skill == NamedSkill("spiral", widened)
    assert load_policy(copy).trained_skill == trained  # what it trained with stays
    assert (copy / "policy.npz").read_bytes() == (shipped / "policy.npz").read_bytes()


def test_catalogue_lists_its_cases_and_classifies_a_few_on_a_fresh_clone(tmp_path):
    names = run_script("experiments/catalogue.py", "--list").splitlines()
    assert len(names) >= 500 and len(set(names)) == len(names)
    groups = {name.split("/")[0] for name in names}
    assert {"edge", "damaged-policy", "kill", "concurrency", "ur5e", "ray", "env", "api"} <= groups
    out = run_script("experiments/catalogue.py", "--out", tmp_path, "--only", "api/skill_config")
    assert "| the Python API | 2 | 2 |" in out  # both one line: a UsageError each
    assert (tmp_path / "clone" / "mjx_peg").is_dir() and (tmp_path / "table.md").is_file()


def test_parts_suite_writes_its_table_resumes_and_refuses_another_run_in_a_folder(tmp_path):
    out = tmp_path / "parts"
    tiny = ["--trials", 2, "--time-limit", 0.3, "--only", "circle-10,hexagon-20", "--out", out]
    text = run_script("experiments/parts_suite.py", "--policy", "baseline", *tiny)
    assert "| hexagon-20 (held out) | baseline |" in text and "| circle-10 | baseline |" in text
    rows = list(csv.DictReader(open(out / "parts.csv")))
    assert [(r["part"], r["trials"]) for r in rows] == [("circle-10", "2"), ("hexagon-20", "2")]
    assert (out / "parts.png").stat().st_size > 0
    before = (out / "baseline" / "circle-10.csv").stat().st_mtime_ns
    assert run_script("experiments/parts_suite.py", "--policy", "baseline", *tiny) == text
    assert (out / "baseline" / "circle-10.csv").stat().st_mtime_ns == before  # resumed, not rerun
    # a folder recorded before a constant of the skill was added resumes where the skill holds
    # the constant at its default (off), and is another run's where the skill turns it on
    record = (out / "baseline" / "suite.json").read_text()
    saved = json.loads(record)
    del saved["skill"]["spiral_axial_ref"], saved["skill"]["part_scale"]
    (out / "baseline" / "suite.json").write_text(json.dumps(saved))
    assert run_script("experiments/parts_suite.py", "--policy", "baseline", *tiny) == text
    saved = json.loads(record)
    del saved["skill"]["spiral_yaw"]  # the shipped spiral sweeps its yaw: 0.1 rad, not 0
    (out / "baseline" / "suite.json").write_text(json.dumps(saved))
    done = run("experiments/parts_suite.py", "--policy", "baseline", *tiny)
    assert done.returncode != 0 and "(its skill differs)" in done.stderr
    (out / "baseline" / "suite.json").write_text(record)
    done = run("experiments/parts_suite.py", "--policy", "baseline=quick", *tiny)
    assert (
        done.returncode != 0
        and "holds the suite of another run (its policy differs)" in done.stderr
    )
    # a constant of the skill changed for every policy is recorded, and refused beside another
    changed = ["--skill-constant", "spiral_pitch=0.002"]
    done = run("experiments/parts_suite.py", "--policy", "baseline", *changed, *tiny)
    assert done.returncode != 0 and "(its skill differs)" in done.stderr
    run_script("experiments/parts_suite.py", "--policy", "pitch=baseline", *changed, *tiny)
    record = json.loads((out / "pitch" / "suite.json").read_text())
    assert record["skill"]["spiral_pitch"] == 0.002
    # a screen of the first trials runs the suite's own first trials
    text = run_script("experiments/parts_suite.py", "--policy", "first=baseline", "--first", 1,
                      *tiny)  # fmt: skip
    assert "the first 1 of 2 trials per part" in text
    for part in ("circle-10", "hexagon-20"):
        screen = list(csv.DictReader(open(out / "first" / f"{part}.csv")))
        whole = list(csv.DictReader(open(out / "baseline" / f"{part}.csv")))
        assert screen == whole[:1]


def _suite_csv(path: Path, success, stops, times) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["trial", "success", "time_s", "protective_stop", "chatter_n",
                         "peak_force_n", "failure"])  # fmt: skip
        for k, (ok, stop, t) in enumerate(zip(success, stops, times, strict=True)):
            writer.writerow([k, ok, t, stop, 1.0, 50.0, "" if ok else "on the rim"])


def test_parts_paired_counts_lost_and_gained_trials_per_part_and_over_all(tmp_path):
    ref, run_dir = tmp_path / "ref", tmp_path / "run"
    _suite_csv(ref / "a.csv", [1, 1, 0, 0, 1], [0, 0, 1, 0, 0], [2.0, 4.0, 60, 60, 3.0])
    _suite_csv(run_dir / "a.csv", [1, 0, 1, 1, 1], [0, 0, 0, 0, 0], [3.0, 60, 5.0, 6.0, 5.0])
    _suite_csv(ref / "b.csv", [0, 0, 1], [0, 0, 0], [60, 60, 1.0])
    _suite_csv(run_dir / "b.csv", [1, 0, 1], [0, 1, 0], [2.0, 60, 1.5])
    _suite_csv(ref / "c.csv", [1], [0], [1.0])  # the run lacks it: not paired
    text = run_script("experiments/parts_paired.py", run_dir, ref)
    rows = {line.split(" | ")[0].strip("| *"): line for line in text.splitlines()[2:]}
    assert set(rows) == {"a", "b", "all 2"}
    # a: 60 -> 80 %, 1 lost / 2 gained; stops 1 -> 0; both inserted trials 0 and 4: 2.5 -> 4 s
    assert rows["a"] == "| a | 5 | 60.0 % | 80.0 % | 1 / 2, p = 1 | 1 → 0 | 2.50 → 4.00 s |"
    assert "| 8 | 50.0 % | 75.0 % | 1 / 3, p = 0.62 | 1 → 1 |" in rows["all 2"]
    # trials 1 and 2 of each part only
    text = run_script("experiments/parts_paired.py", run_dir, ref, "--trials", "1:3")
    assert "| a | 2 | 50.0 % | 50.0 % | 1 / 1, p = 1 | 1 → 0 | - |" in text
    done = run("experiments/parts_paired.py", run_dir, ref, "--trials", "3:1")
    assert done.returncode != 0 and done.stderr.strip().startswith("--trials must be FIRST:END")


def test_the_parts_suite_counts_a_failure_chattering_past_the_approach_only():
    """A touchdown's protective stop at 1.128 s (5.5 N in its window) is a protective stop, not a
    failure that chatters; a failure on the rim at 60 s with 5.5 N is one."""
    sys.path.insert(0, str(ROOT / "experiments"))
    import parts_suite

    from mjx_peg.world.family import SUITE

    rows = [dict(trial=str(k), success=ok, time_s=t, protective_stop=stop, chatter_n=c,
                 peak_force_n="100", failure=cls)
            for k, (ok, t, stop, c, cls) in enumerate((
                ("0", "1.128", "1", "5.526", "protective stop"),
                ("0", "60.000", "0", "5.499", "on the rim"),
                ("0", "60.000", "0", "4.9", "on the rim"),
                ("1", "3.0", "0", "8.0", "")))]  # fmt: skip
    summary = parts_suite.summary("family", SUITE[0], rows)
    assert summary["chatter_failures"] == 1 and summary["protective_stops"] == 1


def test_arm_touchdown_replays_the_tables_trials_at_each_rate(tmp_path):
    """A trial replayed is the UR5e table's trial: at the table's 125 Hz and 5 ms lag its peak
    sensed force is the one the robot CLI recorded for it; a table's early stops are found."""
    cell = tmp_path / "table" / "circle_50mm_6mm"
    argv = ["--policy", "paper", "--shape", "circle", "--size", 50, "--linear-mm", 6,
            "--angular-deg", 12, "--trials", 2, "--command-hz", 125, "--actuator-lag-ms", 5,
            "--time-limit", 0.8, "--seed", 0, "--out", cell, "--no-progress"]  # fmt: skip
    done = subprocess.run([sys.executable, "-m", "mjx_peg.robot", *map(str, argv)], cwd=ROOT,
                          capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    peaks = [float(r["peak_force_n"]) for r in csv.DictReader(open(cell / "runs.csv"))]
    text = run_script("experiments/arm_touchdown.py", "--cell", "circle_50mm_6mm", "--trial", 1,
                      "--table-trials", 2, "--policy", "paper", "--seconds", 0.8)  # fmt: skip
    row = [line for line in text.splitlines() if line.startswith("| circle_50mm_6mm | 1 |")]
    assert len(row) == 1 and row[0].split(" | ")[3] == f"{peaks[1]:.0f} N", (row, peaks)
    (cell / "runs.csv").write_text("trial,success,time_s,protective_stop\n0,1,3.0,0\n"
                                   "1,0,0.9,1\n")  # fmt: skip
    text = run_script("experiments/arm_touchdown.py", "--stops", tmp_path / "table", "--policy",
                      "paper", "--seconds", 0.1)  # fmt: skip
    assert "1 protective stops within 1.2 s" in text and "| circle_50mm_6mm | 1 | paper |" in text
    done = run("experiments/arm_touchdown.py", "--cell", "circle_50mm_7mm", "--trial", 0)
    assert done.returncode != 0 and "is none of the table's cells" in done.stderr


def test_the_wilson_interval_holds_the_rate_at_every_count():
    """At n of n successes the upper end is the rate itself (rounding put it 1e-16 under it, and
    the parts suite's figure then had a negative error bar and failed)."""
    sys.path.insert(0, str(ROOT / "experiments"))
    from ur5e_table import wilson

    for k, n in ((300, 300), (0, 300), (100, 100), (1, 1), (7, 10)):
        low, high = wilson(k, n)
        assert 0.0 <= low <= k / n <= high <= 1.0
    assert wilson(300, 300)[1] == 1.0 and wilson(0, 300)[0] == 0.0


def test_the_ur5e_table_keeps_a_cell_of_its_skill_and_refuses_one_of_another(tmp_path):
    """A finished cell is kept where its skill.json is the skill asked for (one recorded before
    a constant was added reads it as its default), and refused under another skill's constants."""
    sys.path.insert(0, str(ROOT / "experiments"))
    import ur5e_table

    from mjx_peg.policy.export import choose_skill

    cell = tmp_path / "circle_50mm_6mm"
    cell.mkdir()
    (cell / "runs.csv").write_text("trial,success,time_s,protective_stop\n0,1,2.5,0\n")
    record = choose_skill(None, "baseline").record()
    del record["constants"]["spiral_yaw"]  # a cell run before the sweep existed
    (cell / "skill.json").write_text(json.dumps(record))
    rows = ur5e_table.run_cell("baseline", "circle", 50, 6, 1, cell, 0)
    assert rows == [{"trial": "0", "success": "1", "time_s": "2.5", "protective_stop": "0"}]
    with pytest.raises(SystemExit, match="holds a cell of another skill"):
        ur5e_table.run_cell("baseline", "circle", 50, 6, 1, cell, 0, (("spiral_yaw", 0.1),))


def test_the_ur5e_tables_cells_run_as_jobs_keep_the_papers_order(tmp_path):
    """--jobs 2 over finished cells: table.csv lists the cells in the paper's order, each with
    its own runs; --jobs 0 is one line."""
    sys.path.insert(0, str(ROOT / "experiments"))
    import ur5e_table

    from mjx_peg.policy.export import choose_skill

    record = json.dumps(choose_skill(None, "baseline").record())
    for k, (shape, size, linear, _) in enumerate(ur5e_table.CELLS):
        cell = tmp_path / ur5e_table.cell_name(shape, size, linear)
        cell.mkdir()
        (cell / "runs.csv").write_text(f"trial,success,time_s,protective_stop\n0,{k % 2},2.5,0\n")
        (cell / "skill.json").write_text(record)
    argv = ["--policy", "baseline", "--trials", "1", "--out", str(tmp_path)]
    assert ur5e_table.main([*argv, "--jobs", "2"]) == 0
    with open(tmp_path / "table.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["shape"], int(r["size_mm"]), int(r["linear_mm"])) for r in rows] == [
        c[:3] for c in ur5e_table.CELLS
    ]
    assert [int(r["successes"]) for r in rows] == [k % 2 for k in range(len(rows))]
    with pytest.raises(SystemExit, match="--jobs must be at least 1"):
        ur5e_table.main([*argv, "--jobs", "0"])


def test_slot_arithmetic_compares_slot_counts_and_probes_one_period():
    """experiments/slot_arithmetic.py on 24 trials at 64 and 32 slots: a count of the trials
    not bit-identical, none changed in outcome at this size, then one trial's period in every
    slot of a 32- and a 512-slot program (slot 0 never differs from itself)."""
    out = run_script("experiments/slot_arithmetic.py", "--trials", "24", "--slots", "64,32",
                     "--target", "3", "--at", "20", "--probe-slots", "32")  # fmt: skip
    compared = re.search(r"^32 slots against 64: (\d+) of 24 trials differ .*, (\d+) in outcome$",
                         out, flags=re.M)  # fmt: skip
    assert compared and int(compared[1]) <= 24 and int(compared[2]) <= int(compared[1])
    assert "trial 3 at period 20: slot " in out
    for size in (32, 512):
        probe = re.search(rf"its row in all {size} slots: alignment differs from slot 0 in slots "
                          r"\[([\d, ]*)\], torques in \[([\d, ]*)\]", out)  # fmt: skip
        assert probe, out
        for listed in probe.groups():
            slots = [int(x) for x in listed.split(",") if x.strip()]
            assert 0 not in slots and all(0 < k < size for k in slots)


def test_grid_profile_reports_each_stage_and_the_physics_by_part():
    """benchmarks/grid_profile.py with tiny arguments: one lane's stages in µs per env-step,
    which add up to its total, and a step's cost of each part under every collision option."""
    out = run_script("benchmarks/grid_profile.py", "--trials", "8", "--slots", "32",
                     "--physics-trials", "2")  # fmt: skip
    stages = [float(x) for x in re.findall(r"^  [a-z][^:]*: [^\n]*: (\d+\.\d+)$", out, re.M)]
    total = float(re.search(r"^  total: (\d+\.\d+) ", out, re.M)[1])
    assert len(stages) == 8 and abs(sum(stages) - total) < 0.05
    names = ("as shipped", "ccd_iterations 10", "ccd_tolerance 1e-4", "libccd", "mid-phase off")
    for name in names:
        (line,) = re.findall(rf"^  {name}: (.+)$", out, re.M)
        costs = re.findall(r"(circle|square) (\d+\.\d+)", line)
        assert costs and all(float(us) > 0 for _, us in costs), line
