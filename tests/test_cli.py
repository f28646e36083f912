"""mjx_peg/cli.py, the boundary every command line shares: nothing a user types loses data or ends
in a traceback.

Every CLI: bad input is one stderr line and exit status 2, before --out is touched; --force moves
aside only the CLI's own earlier output, never anything else and never an input; results are
written as they are produced; MUJOCO_GL and MuJoCo's log file cannot break or litter a command.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from mjx_peg import cli as shared
from mjx_peg.evaluation import baseline_cli, demo_cli, eval_cli, eval_dir, runner
from mjx_peg.evaluation import config as eval_config
from mjx_peg.learn import cli as train_cli
from mjx_peg.learn.config import TrainConfig
from mjx_peg.policy.export import save_policy
from mjx_peg.policy.observation import LAYOUTS
from mjx_peg.robot import cli as robot_cli
from mjx_peg.skill.search import SKILL_DESCRIPTIONS
from mjx_peg.vision import cli as vision_cli
from mjx_peg.world import scene_cli

ROOT = Path(__file__).resolve().parents[1]
TINY_TRAIN = ["--trials", "1", "--num-envs", "1", "--time-limit", "0.01", "--no-progress"]


def _tree(path: Path) -> dict[str, bytes]:
    """Every file under `path` with its bytes (to prove nothing changed)."""
    return {
        str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()
    }


def _fake_run(path: Path, **config) -> Path:
    """A finished run directory: config.json, policy.npz + manifest.json (no checkpoint)."""
    rng = np.random.default_rng(0)
    conf = TrainConfig(**config)
    n = len(LAYOUTS[conf.observation])  # the numbers its observation layout reads
    layers = [(0.1 * rng.normal(size=(n, 16)), np.zeros(16)), (np.zeros((16, 38)), np.zeros(38))]
    save_policy(path, layers, np.zeros(n), np.ones(n), conf.to_json(), extra={"finished": True})
    (path / "config.json").write_text(conf.dumps())
    return path


def _one_line(capsys, prog: str, *expected: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"{prog}: error: "), err
    assert "Traceback" not in err
    for text in expected:
        assert text in err, err
    return err


def _unwritable_dir(tmp_path: Path) -> Path:
    """An existing directory this process cannot write (root ignores chmod: use /proc/self)."""
    path = tmp_path / "read_only"
    path.mkdir()
    path.chmod(0o555)
    try:
        with tempfile.TemporaryFile(dir=path):
            return Path("/proc/self")
    except OSError:
        return path


# -- data loss: an output never replaces another's, a rerun never loses a result -------------


def test_train_force_never_replaces_a_directory_that_is_not_a_run(tmp_path, capsys):
    mine = tmp_path / "mine"
    (mine / "sub").mkdir(parents=True)
    (mine / "notes.txt").write_text("x\n")
    (mine / "sub" / "data.bin").write_bytes(b"\x00\x01")
    before = _tree(mine)
    code = train_cli.main(["--out", str(mine), "--force", *TINY_TRAIN])
    assert _tree(mine) == before
    assert code == 2
    _one_line(capsys, "train.py", "holds no training run", "--force replaces only a training run")


def test_train_empty_out_is_refused_and_the_default_run_is_kept(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    run = _fake_run(tmp_path / "runs" / "quick")
    before = _tree(run)
    code = train_cli.main(["--out", "", "--force", *TINY_TRAIN])
    assert _tree(run) == before
    assert code == 2
    _one_line(capsys, "train.py", "--out must be a path, got an empty string")


def test_train_init_from_its_own_out_is_refused_and_kept(tmp_path, capsys):
    run = _fake_run(tmp_path / "s")
    before = _tree(run)
    argv = ["--init-from", str(run), "--out", str(run), "--force", *TINY_TRAIN]
    code = train_cli.main(argv)
    assert _tree(run) == before
    assert code == 2
    _one_line(capsys, "train.py", "is the --init-from", "choose another --out")
    # Nor a directory that holds it: moving it aside would take the source along.
    assert train_cli.main([*argv[:3], str(tmp_path), "--force", *TINY_TRAIN]) == 2
    _one_line(capsys, "train.py", "overlaps the --init-from")
    assert _tree(run) == before


def test_train_force_moves_an_earlier_run_aside(tmp_path):
    """--force on a run: the plan is decided without touching anything, then the run is moved
    aside (never deleted) and a fresh directory takes its place."""
    from mjx_peg.learn.run_dir import RunDir

    config = TrainConfig(trials=1, num_envs=1, time_limit_s=0.01)
    run = _fake_run(tmp_path / "run", trials=1, num_envs=1, time_limit_s=0.01)
    before = _tree(run)
    with pytest.raises(ValueError, match="holds a finished run; pass --force"):
        RunDir(run).plan(config, force=False)
    assert RunDir(run).plan(config, force=True) == "replace"
    assert _tree(run) == before  # planning touched nothing
    moved = RunDir(run).prepare(config, "replace")
    assert moved.name.startswith("run.replaced-") and _tree(moved) == before
    assert sorted(p.name for p in run.iterdir()) == ["config.json"]


def test_robot_checks_out_before_any_trial(tmp_path, capsys, monkeypatch):
    from mjx_peg.robot import sim_arm

    ran = []
    real = sim_arm.SimArm
    monkeypatch.setattr(sim_arm, "SimArm", lambda *a, **k: ran.append(1) or real(*a, **k))
    argv = ["--trials", "2", "--time-limit", "0.05", "--no-progress"]
    assert robot_cli.main([*argv, "--out", str(_unwritable_dir(tmp_path))]) == 2
    _one_line(capsys, robot_cli.PROG)
    assert not ran
    # An --out that is a file, or under a file: one line, nothing run.
    (tmp_path / "file").write_text("x")
    for out in (tmp_path / "file", tmp_path / "file" / "sub"):
        assert robot_cli.main([*argv, "--out", str(out)]) == 2
        _one_line(capsys, robot_cli.PROG)
    assert not ran


def test_robot_never_overwrites_runs_csv_without_force(tmp_path, capsys):
    argv = ["--trials", "1", "--time-limit", "0.05", "--no-progress", "--out", str(tmp_path)]
    assert robot_cli.main(argv) == 0
    first = (tmp_path / "runs.csv").read_bytes()
    capsys.readouterr()
    code = robot_cli.main([*argv, "--seed", "3"])
    assert (tmp_path / "runs.csv").read_bytes() == first
    assert code == 2
    _one_line(capsys, robot_cli.PROG, "runs.csv already exists", "--force")
    assert robot_cli.main([*argv, "--seed", "3", "--force"]) == 0
    moved = [p for p in tmp_path.iterdir() if p.name.startswith("runs.csv.replaced-")]
    assert len(moved) == 1 and moved[0].read_bytes() == first
    assert "moved" in capsys.readouterr().err


def test_robot_keeps_every_finished_trial_when_it_crashes(tmp_path, monkeypatch):
    from mjx_peg.robot import runtime

    real, calls = runtime.run_skill, []

    def crash_on_third(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise RuntimeError("the arm's computer crashed")
        return real(*args, **kwargs)

    monkeypatch.setattr(runtime, "run_skill", crash_on_third)
    argv = ["--trials", "5", "--time-limit", "0.05", "--no-progress", "--out", str(tmp_path)]
    with pytest.raises(RuntimeError, match="crashed"):
        robot_cli.main(argv)
    rows = (tmp_path / "runs.csv").read_text().splitlines()
    assert rows[0] == ",".join(robot_cli.COLUMNS) and len(rows) == 3
    assert rows[0].startswith("trial,success,time_s,commands,stopped,protective_stop,settled")


# -- eval.py: --force, corrupt files ----------------------------------------------------------

EVAL = [
    "--policy", "baseline", "--grid", "custom", "--linear-mm", "1,2", "--angular-deg", "1",
    "--trials", "1", "--time-limit", "0.05", "--shape", "square", "--engine", "mujoco",
    "--threads", "1", "--no-progress",
]  # fmt: skip


def test_eval_force_replaces_only_an_evaluation(tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("x\n")
    assert eval_cli.main([*EVAL, "--out", str(mine), "--force"]) == 2
    _one_line(capsys, "eval.py", "is not an evaluation directory", "replaces only an evaluation")
    assert _tree(mine) == {"notes.txt": b"x\n"}

    out = tmp_path / "eval"
    assert eval_cli.main([*EVAL, "--out", str(out)]) == 0
    before = _tree(out)
    capsys.readouterr()
    assert eval_cli.main([*EVAL, "--seed", "5", "--out", str(out)]) == 2
    _one_line(capsys, "eval.py", "different config", "--force")
    assert _tree(out) == before
    assert eval_cli.main([*EVAL, "--seed", "5", "--out", str(out), "--force"]) == 0
    (moved,) = [p for p in tmp_path.iterdir() if p.name.startswith("eval.replaced-")]
    assert _tree(moved) == before
    # Never an input: --out is --compare's evaluation, or holds --policy's run.
    capsys.readouterr()
    assert eval_cli.main([*EVAL, "--out", str(out), "--compare", str(out), "--force"]) == 2
    _one_line(capsys, "eval.py", "is the --compare")
    run = _fake_run(out / "run")
    argv = [*EVAL, "--out", str(out), "--force"]
    argv[argv.index("baseline")] = str(run)
    assert eval_cli.main(argv) == 2
    _one_line(capsys, "eval.py", "overlaps the --policy")


def test_eval_corrupt_range_file_is_one_line_naming_it(tmp_path, capsys, monkeypatch):
    out = tmp_path / "eval"
    assert eval_cli.main([*EVAL, "--out", str(out)]) == 0
    broken = out / "ranges" / "00001.npz"
    broken.write_bytes(broken.read_bytes()[:50])
    (out / "grid.csv").unlink()
    calls = []
    monkeypatch.setattr(runner, "run_trials", lambda *a, **k: calls.append(1))
    capsys.readouterr()
    assert eval_cli.main([*EVAL, "--out", str(out)]) == 2
    _one_line(capsys, "eval.py", str(broken), "corrupt or truncated", "delete it")
    assert not calls and not (out / "grid.csv").exists()


def test_train_corrupt_checkpoint_is_one_line_naming_it(tmp_path):
    """A checkpoint Orbax cannot read: one ValueError line naming it, and nothing else on stderr
    from the TensorStore reads still in flight when Orbax closed its loop (unraisable 'Event loop
    is closed' errors, some before the restore returns, and asyncio 'exception was never
    retrieved' records; whether any is in flight is a race, 5 runs in 12 here without
    learn/restore_noise.py, CI saw both kinds)."""
    code = (
        "import sys, time\n"
        "from mjx_peg.learn import trainer\n"
        "from mjx_peg.learn.config import TrainConfig\n"
        "from mjx_peg.learn.run_dir import RunDir\n"
        "config = TrainConfig(trials=1, num_envs=1, time_limit_s=0.01)\n"
        "run = RunDir(sys.argv[1]); run.prepare(config, 'new')\n"
        "state = trainer.ppo.init_state(config, trainer.ppo.make_networks(config))\n"
        "m = run.checkpoints(); m.save(int(state.iteration), state); m.close()\n"
        "for f in (run.checkpoint_dir / '0').rglob('*'):\n"
        "    if f.is_file() and f.parent.name == 'd': f.write_bytes(f.read_bytes()[:20])\n"
        "try:\n"
        "    trainer.load_state(run.path)\n"
        "except ValueError as e:\n"
        "    print(e, file=sys.stderr)\n"
        "time.sleep(0.5)\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("JAX_")}  # no XLA cache logs
    done = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "run")],
        capture_output=True,
        text=True,
        env={**env, "JAX_PLATFORMS": "cpu"},
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Traceback" not in done.stderr and "Event loop is closed" not in done.stderr
    assert "never retrieved" not in done.stderr
    (line,) = [ln for ln in done.stderr.splitlines() if "corrupt or truncated" in ln]
    assert "checkpoints/0 is corrupt or truncated" in line


# -- one error path, ranges, units ------------------------------------------------------------

CLIS = {
    "train.py": (train_cli.main, []),
    "eval.py": (eval_cli.main, ["--policy", "baseline"]),
    "mjx-peg-demo": (demo_cli.main, []),
    "mjx-peg-baseline": (baseline_cli.main, []),
    "python -m mjx_peg.robot": (robot_cli.main, []),
    "mjx-peg-scene": (scene_cli.main, ["--shape", "circle"]),
}
BAD = [
    # (CLIs, argv, what the one line says)
    ("all", ["--seed", "-1"], "--seed must be an integer in 0..4,294,967,295, got -1"),
    ("all", ["--seed", "99999999999999999999"], "--seed must be an integer in 0..4,294,967,295"),
    ("size", ["--size", "1e-9"], "--size must be a number in [10, 100] mm, got 1e-09"),
    ("size", ["--size", "1e12"], "--size must be a number in [10, 100] mm, got 1e+12"),
    ("size", ["--size", "nan"], "--size must be a number in [10, 100] mm, got 'nan'"),
    ("errors", ["--linear-mm", "51"], "--linear-mm must be a number in [0, 50] mm, got 51"),
    ("errors", ["--angular-deg", "-1"], "--angular-deg must be a number in [0, 45] deg"),
    ("time", ["--time-limit", "1e9"], "--time-limit must be a number in [0.01, 600] s"),
    ("trials", ["--trials", "1000000000"], "--trials must be an integer in 1.."),
    ("trials", ["--trials", "1e3"], "got '1e3'"),
    ("out", ["--out", ""], "--out must be a path, got an empty string"),
]
USES = {
    "all": ("train.py", "eval.py", "mjx-peg-demo", "mjx-peg-baseline", "python -m mjx_peg.robot"),
    "size": ("eval.py", "mjx-peg-demo", "mjx-peg-baseline", "python -m mjx_peg.robot"),
    "errors": ("mjx-peg-demo", "mjx-peg-baseline", "python -m mjx_peg.robot"),
    "time": ("train.py", "eval.py", "mjx-peg-demo", "mjx-peg-baseline", "python -m mjx_peg.robot"),
    "trials": ("train.py", "eval.py", "mjx-peg-baseline", "python -m mjx_peg.robot"),
    "out": ("train.py", "eval.py", "mjx-peg-demo", "python -m mjx_peg.robot", "mjx-peg-scene"),
}


@pytest.mark.parametrize(
    "prog, argv, message",
    [(prog, argv, msg) for group, argv, msg in BAD for prog in USES[group]],
)
def test_every_cli_refuses_bad_values_alike(prog, argv, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    main, required = CLIS[prog]
    extra = ["--out", str(tmp_path / "o")] if prog in ("eval.py", "mjx-peg-scene") else []
    if prog == "mjx-peg-scene":
        extra += ["--size", "50"]
    assert main([*required, *extra, *argv]) == 2
    _one_line(capsys, prog, message)
    assert list(tmp_path.iterdir()) == []  # nothing created, nothing in the working directory


@pytest.mark.parametrize(
    "prog, argv",
    [
        ("eval.py", ["--threads", "100000"]),
        ("eval.py", ["--chunk-trials", "0"]),
        ("eval.py", ["--grid", "custom", "--linear-mm", "0:50:1e-9", "--angular-deg", "1"]),
        ("eval.py", ["--grid", "custom", "--linear-mm", "0:1e308:1e-308", "--angular-deg", "1"]),
        ("eval.py", ["--grid", "paper", "--trials", "100000"]),
        ("train.py", ["--num-envs", "100000000"]),
        ("train.py", ["--threads", "100000"]),
        ("train.py", ["--processes", "100000"]),
        ("eval.py", ["--processes", "-1"]),
        ("train.py", ["--processes", "2", "--engine", "mjx"]),
        ("eval.py", ["--processes", "2", "--engine", "mjx"]),
        ("train.py", ["--checkpoint-every", "nan"]),
        ("mjx-peg-demo", ["--frames", "100000"]),
        ("mjx-peg-scene", ["--width", "100000"]),
        ("python -m mjx_peg.robot", ["--command-hz", "1e9"]),
        ("mjx-peg-baseline", ["--shapes", ","]),
    ],
)
def test_counts_that_would_exhaust_memory_are_refused_up_front(prog, argv, tmp_path, capsys):
    main, required = CLIS[prog]
    extra = ["--out", str(tmp_path / "o")] if prog != "mjx-peg-baseline" else []
    extra += ["--shape", "circle", "--size", "50"] if prog == "mjx-peg-scene" else []
    assert main([*required, *extra, *argv]) == 2
    _one_line(capsys, prog)
    assert not (tmp_path / "o").exists()


def test_processes_default_to_one_per_core_on_the_cpu_engine(monkeypatch):
    """--processes unset: a worker process per core on the mujoco engine (none on one core, none
    on mjx); 0: lanes as threads of this process; a count on mjx is an error."""
    from mjx_peg import cli

    for cores, wanted in ((1, None), (2, 2), (16, 16)):
        monkeypatch.setattr(cli, "cores", lambda n=cores: n)
        assert cli.resolve_processes(None, "mujoco") == wanted
        assert cli.resolve_processes(0, "mujoco") is None
        assert cli.resolve_processes(1, "mujoco") == 1
        assert cli.resolve_processes(None, "mjx") is None
        assert cli.resolve_processes(0, "mjx") is None
        with pytest.raises(ValueError, match="option of the mujoco engine, not of mjx"):
            cli.resolve_processes(2, "mjx")


@pytest.mark.parametrize("prog", ["eval.py", "mjx-peg-demo", "python -m mjx_peg.robot"])
def test_an_out_that_cannot_be_written_is_one_line(prog, tmp_path, capsys):
    main, required = CLIS[prog]
    fast = ["--time-limit", "0.05"] + (["--frames", "0"] if prog == "mjx-peg-demo" else [])
    unwritable = _unwritable_dir(tmp_path)
    for out in (unwritable / "sub", unwritable, tmp_path / ("y" * 300) / "z"):
        assert main([*required, *fast, "--out", str(out)]) == 2
        _one_line(capsys, prog)


def test_help_of_every_numeric_flag_states_its_range():
    for prog in CLIS:
        parser = {
            "train.py": train_cli.parser,
            "eval.py": eval_cli.build_parser,
            "mjx-peg-demo": demo_cli.build_parser,
            "python -m mjx_peg.robot": robot_cli.build_parser,
        }.get(prog)
        if parser is None:
            continue
        for action in parser()._actions:
            if action.type is not None and action.type not in (str, shared.nonempty_path):
                assert "in " in (action.help or ""), (prog, action.option_strings, action.help)


# -- MUJOCO_GL and MuJoCo's log file ----------------------------------------------------------


def _python(*args, cwd, **env):
    return subprocess.run(
        [sys.executable, *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT), "JAX_PLATFORMS": "cpu", **env},
    )


def test_a_bogus_mujoco_gl_breaks_no_command(tmp_path):
    """Bad input is still checked (one line, not an import crash); a command that renders
    falls back to a headless back-end with one warning line."""
    done = _python("-m", "mjx_peg.robot", "--trials", "0", cwd=tmp_path, MUJOCO_GL="bogus")
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines() == [
        "python -m mjx_peg.robot: error: --trials must be an integer in 1..100,000, got 0"
    ]
    args = ("--shape", "square", "--size", "50", "--out", "o", "--width", "64", "--height", "48")
    done = _python("-m", "mjx_peg.world.scene_cli", *args, cwd=tmp_path, MUJOCO_GL="bogus")
    assert done.returncode == 0, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mjx-peg-scene: warning: MUJOCO_GL='bogus'")
    assert (tmp_path / "o" / "scene_square_50mm.png").stat().st_size > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]


def test_mujoco_warnings_go_to_the_output_directory_never_the_working_one(tmp_path):
    """An engine worker process (it imports engines.mujoco) routes MuJoCo's warnings where the
    CLI's environment says: into --out, or nowhere; the simulation still resets on divergence."""
    code = (
        "import mujoco, mjx_peg.engines.mujoco\n"
        "m = mujoco.MjModel.from_xml_string("
        "'<mujoco><worldbody><body><freejoint/><geom size=\"1\"/></body></worldbody></mujoco>')\n"
        "d = mujoco.MjData(m); d.qvel[0] = 1e300; mujoco.mj_step(m, d)\n"
        "assert d.warning[mujoco.mjtWarning.mjWARN_BADQVEL].number == 1 and d.time < 0.01\n"
    )
    (tmp_path / "cwd").mkdir()
    log = tmp_path / "out" / "MUJOCO_LOG.TXT"
    log.parent.mkdir()
    done = _python("-c", code, cwd=tmp_path / "cwd", MJX_PEG_MUJOCO_LOG=str(log))
    assert done.returncode == 0, done.stderr
    assert "simulation is unstable" in log.read_text() and "WARNING" not in done.stdout
    done = _python("-c", code, cwd=tmp_path / "cwd", MJX_PEG_MUJOCO_LOG="")
    assert done.returncode == 0 and done.stdout == "", done.stderr
    assert list((tmp_path / "cwd").iterdir()) == []


@pytest.mark.serial  # reads the whole checkout's state: run alone (README's test command)
def test_bad_input_leaves_a_clone_clean():
    """`git status` of the repository stays as it was after every CLI is given bad input from
    its root (subprocesses, as a user runs them); nothing is created in ignored places either."""
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")

    def state():
        done = subprocess.run(
            ["git", "status", "--porcelain"], cwd=ROOT, capture_output=True, text=True
        )
        made = [n for n in ("runs", "demo_out", "out", "MUJOCO_LOG.TXT") if (ROOT / n).exists()]
        return done.stdout, made

    before = state()
    runs = [
        ("train.py", "--trials", "0"),
        ("eval.py", "--policy", "baseline", "--out", "", "--trials", "1"),
        ("-m", "mjx_peg.evaluation.demo_cli", "--size", "1e12"),
        ("-m", "mjx_peg.evaluation.baseline_cli", "--seed", "-1"),
        ("-m", "mjx_peg.robot", "--command-hz", "300"),
        ("-m", "mjx_peg.world.scene_cli", "--shape", "circle", "--size", "50", "--out", "/proc/x"),
    ]
    for args in runs:
        done = _python(*args, cwd=ROOT, MUJOCO_GL="bogus")
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1, (args, done.stderr)
        assert "error:" in lines[0] and "Traceback" not in done.stderr
    assert state() == before


def test_evaluation_config_json_is_recognised_by_its_schema(tmp_path):
    out = tmp_path / "e"
    out.mkdir()
    (out / "config.json").write_text(json.dumps({"config": {}}))
    config = eval_config.EvalConfig("baseline", "custom", (1.0,), (1.0,), 1, ("square",), 50.0)
    with pytest.raises(ValueError, match="is not an evaluation config"):
        eval_dir.prepare_out_dir(out, config, force=True)
    assert (out / "config.json").exists()


# -- the catalogue's last cases ------------------------------------------------------------------


@pytest.mark.parametrize("prog", [p for p in CLIS if p != "mjx-peg-baseline"])  # no --out there
def test_a_symlink_loop_as_out_is_one_line(prog, tmp_path, capsys):
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    main, required = CLIS[prog]
    assert main([*required, "--out", str(tmp_path / "a")]) == 2
    _one_line(capsys, prog, "is a symbolic link loop")


@pytest.mark.parametrize("hz", ["5e-324", "1e-12", "0.5"])
def test_a_command_period_longer_than_the_trial_is_one_line(hz, tmp_path, capsys):
    out = tmp_path / "o"
    assert robot_cli.main(["--command-hz", hz, "--time-limit", "1", "--out", str(out)]) == 2
    _one_line(capsys, "python -m mjx_peg.robot", "longer than the --time-limit of 1 s")
    assert not out.exists()


def test_a_second_evaluation_of_the_same_out_is_refused_while_the_first_holds_it(
    tmp_path, capsys, hold_out
):
    """The lock is held while its process lives, and gone with it when it is killed."""
    out = tmp_path / "eval"
    holder = hold_out(out)
    try:
        argv = [
            "--policy",
            "baseline",
            "--out",
            str(out),
            "--grid",
            "custom",
            "--linear-mm",
            "1",
            "--angular-deg",
            "1",
            "--trials",
            "1",
            "--time-limit",
            "0.05",
            "--no-progress",
        ]
        assert eval_cli.main(argv) == 2
        _one_line(capsys, "eval.py", f"--out {out} is in use by another process (pid")
        assert not out.exists()
    finally:
        holder.kill()  # as a crash: the lock must not stay behind
        holder.wait()
    assert eval_cli.main(argv) == 0
    assert (out / "grid.csv").is_file()


def test_a_bug_inside_an_engine_keeps_its_traceback(tmp_path, capsys, monkeypatch):
    """Only UsageError and OSError become one line: an internal ValueError is a bug and
    propagates through cli.entry; a bad flag is still one line."""
    from mjx_peg.engines import period

    def broken(*args):
        raise ValueError("operands could not be broadcast together")

    monkeypatch.setattr(period, "skill_torque", broken)
    argv = ["--policy", "baseline", "--out", str(tmp_path / "o"), "--grid", "custom",
            "--linear-mm", "1", "--angular-deg", "1", "--trials", "1", "--time-limit", "0.05",
            "--no-progress", "--processes", "0"]  # fmt: skip
    with pytest.raises(ValueError, match="could not be broadcast"):
        eval_cli.main(argv)
    assert eval_cli.main([*argv, "--seed", "-1"]) == 2
    _one_line(capsys, "eval.py", "--seed must be an integer")


def test_train_rounds_its_budget_up_to_whole_iterations_and_says_so(tmp_path, capsys):
    argv = ["--trials", "3", "--num-envs", "2", "--time-limit", "0.01", "--no-progress"]
    assert train_cli.main(["--out", str(tmp_path / "run"), *argv]) == 0
    err = capsys.readouterr().err
    assert "--trials 3 rounded up to 2 iterations of 2 trials (4 trials)" in err
    assert "rounded up to whole iterations" in train_cli.parser().format_help().replace("\n ", "")


@pytest.mark.slow
@pytest.mark.serial  # timed: run alone (README's test command)
def test_ctrl_c_stops_training_within_3_s_and_it_resumes_to_the_same_trials(tmp_path):
    """SIGINT in the middle of an iteration (the main thread waiting in the jitted PPO step,
    the CPU engine in a host callback): exit 130 within 3 s, every finished iteration kept;
    the same command then finishes with the trials.csv of an uninterrupted run."""
    import functools
    import signal
    import time

    # 4 s trials: an iteration of ~4 s here, the signal 1 s into its trials
    argv = ["train.py", "--num-envs", "8", "--trials", "16", "--time-limit", "4",
            "--checkpoint-every", "3600", "--no-progress", "--processes", "0"]  # fmt: skip
    out = tmp_path / "run"
    env = dict(os.environ)  # the tests' compilation cache: each of the three runs compiles once
    # The uninterrupted run beside the interrupted one and its resumption (one core each)
    whole = subprocess.Popen([sys.executable, *argv, "--out", str(tmp_path / "uninterrupted")],
                             cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             text=True)  # fmt: skip
    try:
        # SIGINT back to its default in the child: a suite run as a background job ignores it
        default = functools.partial(signal.signal, signal.SIGINT, signal.SIG_DFL)
        run = subprocess.Popen([sys.executable, *argv, "--out", str(out)], cwd=ROOT, env=env,
                               stderr=subprocess.PIPE, text=True, preexec_fn=default)  # fmt: skip
        csv = out / "trials.csv"
        deadline = time.monotonic() + 600
        while not (csv.is_file() and len(csv.read_text().splitlines()) > 8):
            assert run.poll() is None and time.monotonic() < deadline
            time.sleep(0.1)
        time.sleep(1.0)  # into the second iteration's trials
        sent = time.monotonic()
        run.send_signal(signal.SIGINT)
        assert run.wait(timeout=60) == 130
        took = time.monotonic() - sent
        assert took < 3.0, took
        assert "interrupted; rerun the same command to resume" in run.stderr.read()
        assert len(csv.read_text().splitlines()) == 9  # the first iteration, kept
        resumed = subprocess.Popen([sys.executable, *argv, "--out", str(out)], cwd=ROOT,
                                   env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                   text=True)  # fmt: skip
        for done in (resumed, whole):
            _, err = done.communicate(timeout=900)
            assert done.returncode == 0, err[-2000:]
    finally:  # a failed check leaves no training running
        if whole.poll() is None:
            whole.kill()
    assert csv.read_bytes() == (tmp_path / "uninterrupted" / "trials.csv").read_bytes()


def test_parse_ranges():
    assert shared.parse_ranges("0.5, 1,2", "--linear-mm") == (0.5, 1.0, 2.0)
    assert shared.parse_ranges("1:3:1,4.5", "--linear-mm") == (1.0, 2.0, 3.0, 4.5)
    assert len(shared.parse_ranges("0.32:8:0.32", "--linear-mm")) == 25
    for bad in ("", " , ", "3:1:1"):
        with pytest.raises(ValueError, match="--linear-mm is empty"):
            shared.parse_ranges(bad, "--linear-mm")
    with pytest.raises(ValueError, match="cannot read"):
        shared.parse_ranges("1,x", "--linear-mm")


@pytest.mark.parametrize(
    "main, argv",
    [(eval_cli.main, []), (train_cli.main, []), (baseline_cli.main, []), (robot_cli.main, []),
     (vision_cli.main, ["act"])],
)  # fmt: skip
def test_every_skill_option_describes_both_skills(main, argv, capsys):
    """--skill offers the two skills a user chooses between, and its help says what each is."""
    assert main([*argv, "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--skill {paper,spiral}" in text
    for name, description in SKILL_DESCRIPTIONS.items():
        assert f"{name}: {description}" in text


def test_a_stopped_command_exits_without_the_interpreters_finalization(tmp_path):
    """A signal once the command works (SIGTERM: a test runner's workers may start their
    children with SIGINT ignored): one line, 143, and the process ends without the interpreter's
    exit (atexit handlers, native threads' teardown), multiprocessing's semaphores released first
    (no 'leaked semaphore' report)."""
    import subprocess
    import sys

    script = tmp_path / "stopped.py"
    script.write_text(
        "import atexit, multiprocessing, os, signal, time\n"
        "from mjx_peg import cli, signals\n"
        "@cli.entry('stopped')\n"
        "def main(argv=None):\n"
        "    lock = multiprocessing.get_context('spawn').Lock()\n"
        "    atexit.register(print, 'finalized')\n"
        "    signals.working()\n"
        "    os.kill(os.getpid(), signal.SIGTERM)\n"
        "    time.sleep(5)\n"
        "    return 0\n"
        "main()\n"
    )
    done = subprocess.run([sys.executable, script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 143
    assert done.stderr.strip() == "stopped: terminated"
    assert "finalized" not in done.stdout
