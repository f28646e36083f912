"""The command lines' one-line errors say which flag and what is wrong, and nothing is written
before the input is accepted (`mjx_peg/cli.py` and the commands' checks)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mjx_peg.evaluation import baseline_cli, demo_cli, eval_cli
from mjx_peg.learn import cli as train_cli
from mjx_peg.policy import shipped
from mjx_peg.robot import cli as robot_cli
from mjx_peg.vision import cli as vision_cli

ROOT = Path(__file__).resolve().parents[1]
LONG = "p" * 5000


def _error(capsys, main, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err.strip()


@pytest.mark.parametrize(
    "main, argv, expected",
    [
        (robot_cli.main, ["--command-hz", "500.0001"], "got 500.0001"),
        (robot_cli.main, ["--command-hz", "333"], "divide the 500 Hz physics"),
        (robot_cli.main, ["--dry-run", "--hole", "-450,120,30"],
         "--hole expects a value; one that starts with '-' is written --hole=-VALUE"),
        (robot_cli.main, ["--model", "controller"], "--model controller asks a UR5e's controller"),
        (robot_cli.main, ["--friction-comp"], "--friction-comp asks a UR5e's controller"),
        (baseline_cli.main, ["--shapes", "circle,circle"], "--shapes names a shape twice"),
        (vision_cli.main, ["render", "--out", "split", "--count", "1", "--sizes", "90"],
         "--sizes must be sizes S in mm, each in [10, 80], got '90'"),
        (vision_cli.main, ["render", "--out", "split", "--count", "1", "--shapes", "octagon"],
         "--shapes must name shapes of circle, square, triangle, hexagon, rectangle"),
        (baseline_cli.main, ["--hole-scale", "1.3"], "--hole-scale must be paper or tight or a "
         "number in [1.01, 1.25]"),
        (demo_cli.main, ["--hole-scale", "nan"], "--hole-scale must be paper or tight"),
        (train_cli.main, ["--seed", "1", "--seeds", "1,2"], "--seed and --seeds: give one of them"),
    ],
)  # fmt: skip
def test_a_bad_value_is_named_with_its_flag(main, argv, expected, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert expected in _error(capsys, main, argv)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "main, argv",
    [
        (robot_cli.main, ["--trials", "1"]),
        (eval_cli.main, ["--out", "e"]),
        (demo_cli.main, ["--out", "d"]),
        (vision_cli.main, ["act", "--out", "a"]),
    ],
)
def test_a_5000_character_policy_is_shortened_in_a_line_naming_the_flag(
    main, argv, tmp_path, monkeypatch, capsys
):
    monkeypatch.chdir(tmp_path)
    err = _error(capsys, main, [*argv, "--policy", LONG])
    assert "--policy" in err and "(5,000 characters)" in err and len(err) < 300, err
    assert list(tmp_path.iterdir()) == []


def test_a_directory_given_as_a_camera_calibration_is_called_one(tmp_path, capsys):
    from PIL import Image

    Image.fromarray(np.zeros((48, 64, 3), np.uint8)).save(tmp_path / "img.png")
    err = _error(capsys, vision_cli.main, ["localize", str(tmp_path / "img.png"), "--camera",
                                           str(tmp_path)])  # fmt: skip
    assert f"{tmp_path}: is a directory, not a file" in err


def _damaged_policy(tmp_path) -> Path:
    run = tmp_path / "policy"
    shutil.copytree(shipped.SHIPPED_DIR / "quick", run)
    doc = json.loads((run / "manifest.json").read_text())
    doc["config"] = [1]
    (run / "manifest.json").write_text(json.dumps(doc))
    return run


def _bad_split(tmp_path) -> Path:
    from mjx_peg.vision import dataset

    split = tmp_path / "split"
    split.mkdir()
    config = dataset.SplitConfig(count=1, seed=0)
    (split / dataset.MANIFEST).write_text(
        json.dumps({"schema": dataset.SCHEMA, "config": config.to_json()})
    )
    (split / "000000.json").write_text("[]")
    return split


@pytest.mark.parametrize(
    "command",
    ["robot", "robot --rehearse", "eval", "demo", "vision act", "vision evaluate",
     "vision train"],
)  # fmt: skip
def test_nothing_is_written_before_the_input_is_accepted(command, tmp_path, capsys):
    """A damaged policy or split: one line naming it, and no --out (nor its parents) made."""
    out = str(tmp_path / "new" / "out")
    policy = str(_damaged_policy(tmp_path))
    split = str(_bad_split(tmp_path))
    main, argv = {
        "robot": (robot_cli.main, ["--policy", policy, "--out", out]),
        "robot --rehearse": (robot_cli.main, ["--rehearse", "--hole", "450,-120,30", "--policy",
                                              policy, "--out", out]),
        "eval": (eval_cli.main, ["--policy", policy, "--out", out]),
        "demo": (demo_cli.main, ["--policy", policy, "--out", out]),
        "vision act": (vision_cli.main, ["act", "--policy", policy, "--out", out]),
        "vision evaluate": (vision_cli.main, ["evaluate", "--data", split, "--out", out]),
        "vision train": (vision_cli.main, ["train", "--data", split, "--out", out]),
    }[command]  # fmt: skip
    err = _error(capsys, main, argv)
    assert ("manifest.json: config is not an object" in err) or ("000000.json" in err), err
    assert not (tmp_path / "new").exists()


def _python(*args, **env) -> subprocess.CompletedProcess:
    environ = {**os.environ, "PYTHONPATH": str(ROOT), "JAX_PLATFORMS": "cpu", **env}
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=environ, capture_output=True,
                          text=True, timeout=300)  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize(
    "argv",
    [
        ["-m", "mjx_peg.robot", "--trials", "1", "--time-limit", "0.05", "--no-progress",
         "--out", "{tmp}"],
        ["-m", "mjx_peg.evaluation.baseline_cli", "--trials", "1", "--time-limit", "0.05",
         "--shapes", "circle"],
    ],
)  # fmt: skip
def test_an_ascii_terminal_gets_the_plus_minus_sign_escaped(argv, tmp_path):
    done = _python(*(a.format(tmp=tmp_path) for a in argv), PYTHONIOENCODING="ascii")
    assert done.returncode == 0, done.stderr[-2000:]
    assert "\\xb1" in done.stdout and "Traceback" not in done.stderr


@pytest.mark.slow
@pytest.mark.parametrize("platforms", ["cuda", "bogus"])
def test_a_jax_platform_that_cannot_start_is_one_line(platforms, tmp_path):
    done = _python("train.py", "--trials", "8", "--num-envs", "8", "--out", str(tmp_path / "run"),
                   JAX_PLATFORMS=platforms)  # fmt: skip
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr[-2000:]
    assert lines[0].startswith(f"train.py: error: JAX_PLATFORMS={platforms!r}")
    assert not (tmp_path / "run").exists()
