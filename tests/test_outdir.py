"""mjx_peg/outdir.py: the resumable output directory, --force that moves aside, atomic writes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mjx_peg import outdir
from mjx_peg.errors import UsageError
from mjx_peg.outdir import OutDir, write_json, write_npz

CONFIG = {"seed": 0, "shapes": ("circle", "square"), "count": 4}


def _tree(path: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()
    }


def _outdir(path: Path, **kwargs) -> OutDir:
    return OutDir(path, "config.json", "evaluation", **kwargs)


def test_a_new_directory_records_its_config_and_resumes_with_the_same(tmp_path):
    out = _outdir(tmp_path / "out")
    assert out.open(CONFIG) == "new"
    assert json.loads((tmp_path / "out" / "config.json").read_text()) == {
        "seed": 0, "shapes": ["circle", "square"], "count": 4,
    }  # fmt: skip
    (tmp_path / "out" / "result.txt").write_text("kept\n")
    before = _tree(tmp_path / "out")
    assert out.plan(dict(CONFIG), force=False) == "resume"  # tuples and lists are one config
    assert out.open(CONFIG) == "resume"
    assert _tree(tmp_path / "out") == before
    assert _outdir(tmp_path / "empty").plan(CONFIG, force=False) == "new"


def test_another_config_is_one_line_naming_the_keys_that_differ(tmp_path):
    out = _outdir(tmp_path / "out")
    out.open(CONFIG)
    before = _tree(out.path)
    with pytest.raises(UsageError) as caught:
        out.plan({**CONFIG, "seed": 7, "count": 5}, force=False)
    text = str(caught.value)
    assert "\n" not in text and text.startswith(f"--out {out.path} holds an evaluation")
    assert "different config (seed: 0 there, 7 now; count differs too)" in text
    assert "choose another --out, or pass --force to move it aside" in text
    assert _tree(out.path) == before
    # A key in `ignore` may change: it is resumed, and the new document recorded.
    growing = _outdir(out.path, ignore=("count",))
    assert growing.plan({**CONFIG, "count": 5}, force=False) == "resume"
    growing.prepare("resume", {**CONFIG, "count": 5})
    assert json.loads(out.config_path.read_text())["count"] == 5


def test_force_moves_the_directory_aside_and_says_where(tmp_path):
    out = _outdir(tmp_path / "out")
    out.open(CONFIG)
    (out.path / "result.txt").write_text("earlier\n")
    before = _tree(out.path)
    notes = []
    assert out.open({**CONFIG, "seed": 1}, force=True, note=notes.append) == "replace"
    (moved,) = [p for p in tmp_path.iterdir() if p.name.startswith("out.replaced-")]
    assert _tree(moved) == before  # nothing deleted
    assert notes == [f"--force: moved the earlier evaluation in {out.path} aside to {moved}"]
    assert sorted(p.name for p in out.path.iterdir()) == ["config.json"]
    assert json.loads(out.config_path.read_text())["seed"] == 1


def test_force_replaces_nothing_but_its_own_kind(tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("x\n")
    with pytest.raises(UsageError, match="is not an evaluation directory .*holds no evaluation"):
        _outdir(mine).plan(CONFIG, force=True)
    (tmp_path / "file").write_text("x\n")
    with pytest.raises(UsageError, match="exists and is not a directory"):
        _outdir(tmp_path / "file").plan(CONFIG, force=True)
    # A config file that does not read as this kind's: refused, force or not.
    (mine / "config.json").write_text("{not json")
    with pytest.raises(UsageError, match=r"config.json is not an evaluation config \(Expecting"):
        _outdir(mine).plan(CONFIG, force=True)

    def schema(doc):
        if doc.get("schema") != "mine":
            raise ValueError("no mine schema")
        return doc["config"]

    (mine / "config.json").write_text(json.dumps({"config": CONFIG}))
    with pytest.raises(UsageError, match=r"is not an evaluation config \(no mine schema\)"):
        _outdir(mine, read=schema).plan(CONFIG, force=True)
    assert _tree(mine) == {
        "notes.txt": b"x\n",
        "config.json": json.dumps({"config": CONFIG}).encode(),
    }
    assert [p.name for p in tmp_path.iterdir() if ".replaced-" in p.name] == []


class _Unwritable:
    def __array__(self, *args, **kwargs):
        raise RuntimeError("the disk went away")


def test_a_failed_write_leaves_the_old_file_and_no_partial_one(tmp_path):
    path = tmp_path / "r.npz"
    write_npz(path, {"a": np.arange(3)})
    with np.load(path, allow_pickle=False) as npz:
        assert npz["a"].tolist() == [0, 1, 2]
    before = path.read_bytes()
    with pytest.raises(RuntimeError, match="went away"):  # after the first array was written
        write_npz(path, {"a": np.arange(4), "b": _Unwritable()})
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.npz"]

    doc = tmp_path / "d.json"
    write_json(doc, {"x": 1})

    def half(tmp):
        tmp.write_text('{"x": ')
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError):
        outdir.write_atomic(doc, half)
    assert doc.read_text() == '{\n  "x": 1\n}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.json", "r.npz"]
    write_json(doc, {"x": [1, 2]}, indent=None)
    assert doc.read_text() == '{"x": [1, 2]}\n'


def test_an_output_never_overlaps_an_input(tmp_path):
    policy = tmp_path / "runs" / "quick"
    for out in (policy, policy / "eval", tmp_path / "runs"):
        with pytest.raises(UsageError, match="an output never replaces an input") as caught:
            outdir.check_apart(out, {"--policy": policy})
        assert "--out" in str(caught.value) and "--policy" in str(caught.value)
    outdir.check_apart(tmp_path / "eval", {"--policy": policy, "--compare": None})
    outdir.check_apart(policy, {"--policy": "baseline"})  # a name, not a path


def test_earlier_results_are_refused_or_moved_aside_never_deleted(tmp_path):
    picture, table = tmp_path / "a.png", tmp_path / "b.csv"
    picture.write_bytes(b"png")
    with pytest.raises(UsageError, match=r"a.png already exists: choose another --out, or pass "
                       r"--force to move it aside"):  # fmt: skip
        outdir.refuse_or_move([picture, table], force=False)
    notes = []
    outdir.refuse_or_move([picture, table], force=True, note=notes.append)
    (moved,) = [p for p in tmp_path.iterdir() if p.name.startswith("a.png.replaced-")]
    assert moved.read_bytes() == b"png" and not picture.exists() and not table.exists()
    assert notes == [f"--force: moved {picture} aside to {moved}"]
    picture.write_bytes(b"again")
    again = outdir.move_aside(picture)  # the same second: a numbered name beside the first
    assert again != moved and again.read_bytes() == b"again"


# -- one writer per output directory (outdir.exclusive) -----------------------------------------


@pytest.mark.parametrize("kind", ["symlink", "hardlink", "directory", "fifo"])
def test_a_lock_path_that_is_not_a_lock_file_is_refused_and_nothing_is_written_through_it(
    kind, tmp_path
):
    """`ln -s victim.txt .out.lock` (or a hard link, a folder, a FIFO): one line naming --out,
    the victim untouched, nothing created."""
    import os

    from mjx_peg import outdir

    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    lock = outdir.lock_path(tmp_path / "out")
    if kind == "symlink":
        lock.symlink_to(victim)
    elif kind == "hardlink":
        os.link(victim, lock)
    elif kind == "directory":
        lock.mkdir()
    else:
        os.mkfifo(lock)
    with pytest.raises(UsageError, match=r"^--out .*/out: its lock .* remove it$"):
        with outdir.exclusive(tmp_path / "out"):
            pass
    assert victim.read_text() == "precious\n" and not (tmp_path / "out").exists()


def test_the_lock_goes_with_its_holder_and_a_refused_input_leaves_no_folder(tmp_path):
    from mjx_peg import outdir

    out = tmp_path / "a" / "b" / "out"
    with outdir.exclusive(out):
        assert outdir.lock_path(out).read_text() == f"{__import__('os').getpid()}\n"
        out.mkdir()
        (out / "result.txt").write_text("x")
    assert not outdir.lock_path(out).exists() and (out / "result.txt").exists()
    other = tmp_path / "c" / "d" / "out"
    with pytest.raises(UsageError, match="bad input"):
        with outdir.exclusive(other):
            other.mkdir()  # made, then the input is refused: nothing is left behind
            raise UsageError("bad input")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"]


def test_every_command_that_writes_an_output_directory_refuses_a_second_writer(
    tmp_path, capsys, hold_out
):
    """While another process holds --out: one line naming --out and the holder's pid, before
    anything is written (the holder's files untouched); once it is gone, the command runs."""
    from mjx_peg.evaluation import demo_cli
    from mjx_peg.robot import cli as robot_cli
    from mjx_peg.vision import cli as vision_cli
    from mjx_peg.world import scene_cli

    out = tmp_path / "out"
    out.mkdir()
    (out / "theirs.txt").write_text("the first writer's\n")
    holder = hold_out(out)
    commands = {
        robot_cli: ["--trials", "1", "--time-limit", "0.05", "--no-progress"],
        demo_cli: ["--frames", "0", "--time-limit", "0.05"],
        scene_cli: ["--shape", "circle", "--size", "50", "--width", "16", "--height", "16"],
        vision_cli: ["render", "--count", "1", "--width", "64", "--height", "64"],
    }
    try:
        for cli_module, argv in commands.items():
            assert cli_module.main([*argv, "--out", str(out)]) == 2
            err = capsys.readouterr().err.strip()
            assert len(err.splitlines()) == 1, err
            assert f"--out {out} is in use by another process (pid {holder.pid})" in err
        assert sorted(p.name for p in out.iterdir()) == ["theirs.txt"]
    finally:
        holder.kill()
        holder.wait()
    assert robot_cli.main([*commands[robot_cli], "--out", str(out)]) == 0


@pytest.mark.slow
def test_two_trainings_on_one_out_a_few_seconds_apart_the_second_is_refused(tmp_path):
    """The same train.py twice, 2 s apart: the second refused in one line, the first's run
    whole (every trial once in trials.csv, every iteration once in metrics.csv)."""
    import os
    import subprocess
    import sys
    import time

    root = Path(__file__).resolve().parents[1]
    argv = [sys.executable, "train.py", "--num-envs", "8", "--trials", "32", "--time-limit",
            "0.5", "--checkpoint-every", "0", "--seed", "3", "--processes", "0", "--no-progress",
            "--out", str(tmp_path / "run")]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(root), "JAX_PLATFORMS": "cpu"}
    first = subprocess.Popen(argv, cwd=root, env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True)  # fmt: skip
    deadline = time.monotonic() + 300
    while not (tmp_path / "run" / "config.json").exists():
        assert first.poll() is None and time.monotonic() < deadline
        time.sleep(0.1)
    time.sleep(2)
    second = subprocess.run([*argv[:-2], "--seed", "4", *argv[-2:]], cwd=root, env=env,
                            capture_output=True, text=True, timeout=300)  # fmt: skip
    assert first.wait(timeout=600) == 0, first.stderr.read()[-2000:]
    lines = second.stderr.strip().splitlines()
    assert second.returncode == 2 and len(lines) == 1, second.stderr
    assert f"--out {tmp_path / 'run'} is in use by another process (pid {first.pid})" in lines[0]
    trials = (tmp_path / "run" / "trials.csv").read_text().splitlines()[1:]
    assert [int(row.split(",")[0]) for row in trials] == list(range(32))
    metrics = (tmp_path / "run" / "metrics.csv").read_text().splitlines()[1:]
    assert [int(row.split(",")[0]) for row in metrics] == list(range(1, 5))
    assert json.loads((tmp_path / "run" / "config.json").read_text())["seed"] == 3


def test_files_written_together_are_all_there_or_none(tmp_path):
    """A full disk at the second file (the scene's PNG after its MJCF, the demo's frames after
    its plot): the first is removed again, so the same command reruns without --force."""
    from mjx_peg import outdir

    def full(path):
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError) as caught:
        outdir.write_all_atomic([(tmp_path / "a.xml", "<a/>"), (tmp_path / "a.png", full)])
    assert caught.value.filename == str(tmp_path / "a.png")
    assert list(tmp_path.iterdir()) == []
    written = outdir.write_all_atomic([(tmp_path / "a.xml", "<a/>"), (tmp_path / "b", b"x")])
    assert [p.read_bytes() for p in written] == [b"<a/>", b"x"]
