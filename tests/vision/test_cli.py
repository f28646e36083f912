"""vision/cli.py (`python -m mjx_peg.vision`): one-line errors, the shipped localizer by default,
the skill of `act`, and inference without JAX or MuJoCo."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mjx_peg.vision import cli
from mjx_peg.vision.camera import CalibrationError, CameraCalibration


def _one_line_error(capsys, argv) -> str:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_bad_input_is_one_line(tmp_path, capsys):
    calib = CameraCalibration.from_mujoco((0.35, 0, 1.3), np.eye(3), 45.0, 64, 48)
    good = calib.save(tmp_path / "camera.json")
    err = _one_line_error(
        capsys, ["localize", str(tmp_path / "missing.png"), "--camera", str(good)]
    )
    assert "does not exist" in err
    from PIL import Image

    Image.fromarray(np.zeros((48, 64, 3), np.uint8)).save(tmp_path / "img.png")
    doc = calib.to_json()
    del doc["intrinsics"]
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    err = _one_line_error(
        capsys, ["localize", str(tmp_path / "img.png"), "--camera", str(tmp_path / "bad.json")]
    )
    assert "intrinsics" in err
    err = _one_line_error(
        capsys,
        [
            "localize",
            str(tmp_path / "img.png"),
            "--camera",
            str(good),
            "--model",
            str(tmp_path / "nomodel"),
        ],
    )
    assert "train one first" in err
    _one_line_error(
        capsys, ["render", "--out", str(tmp_path / "r"), "--count", "2", "--condition", "foggy"]
    )
    err = _one_line_error(
        capsys,
        [
            "evaluate",
            "--model",
            str(tmp_path / "m"),
            "--data",
            str(tmp_path / "d"),
            "--out",
            str(tmp_path / "m" / "eval"),
        ],
    )
    assert "an output never replaces an input" in err
    _one_line_error(capsys, ["act", "--out", str(tmp_path / "a"), "--trials", "0"])
    with pytest.raises(CalibrationError):
        CameraCalibration.from_json(doc | {"intrinsics": {"fx": 1, "fy": 1, "cx": 0}})


def test_reading_commands_default_to_the_shipped_localizer():
    """evaluate, localize, act and figures read policies/localizer without --model (and it loads);
    train writes a new one to runs/vision/model."""
    from pathlib import Path

    from mjx_peg.policy.shipped import SHIPPED_DIR
    from mjx_peg.vision.localizer import Localizer

    parser = cli.build_parser()
    for argv in (
        ["evaluate", "--data", "d", "--out", "o"],
        ["localize", "img.png", "--camera", "c.json"],
        ["act", "--out", "o"],
        ["figures", "--data", "d"],
    ):
        assert parser.parse_args(argv).model == SHIPPED_DIR / "localizer"
    assert parser.parse_args(["train", "--data", "d"]).out == Path("runs/vision/model")
    assert Localizer.load(SHIPPED_DIR / "localizer") is not None


@pytest.mark.parametrize("skill", [None, "spiral"])
def test_act_runs_the_named_skill(tmp_path, monkeypatch, skill):
    """`act --skill NAME` runs that skill; without it, the policy's own (run_act's None)."""
    from mjx_peg.vision import act, localizer

    seen = {}

    def fake_run_act(loc, policy, out, *args, skill=None, **kwargs):
        seen["skill"] = skill
        return {"all": dict.fromkeys(("vision_success", "sampled_success", "exact_success"), 1)}

    monkeypatch.setattr(act, "run_act", fake_run_act)
    shipped = localizer.Localizer.load(cli.SHIPPED_MODEL)  # act checks it localizes the shapes
    monkeypatch.setattr(localizer.Localizer, "load", staticmethod(lambda path: shipped))
    argv = ["act", "--out", str(tmp_path / "a"), "--trials", "1", "--no-progress"]
    assert cli.main(argv + (["--skill", skill] if skill else [])) == 0
    assert seen == {"skill": skill}


def test_inference_needs_neither_jax_nor_mujoco():
    """The robot's computer can localize: the localizer and the CLI's parser import NumPy only."""
    import subprocess
    import sys

    code = (
        "import sys, mjx_peg.vision.localizer, mjx_peg.vision.cli; "
        "bad = [m for m in sys.modules if m.split('.')[0] in ('jax', 'flax', 'mujoco', 'optax')]; "
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def _files(path) -> dict[str, bytes]:
    return {
        str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()
    }


def test_vision_render_resumes_refuses_and_moves_aside_with_force(tmp_path, capsys):
    out = tmp_path / "split"
    argv = ["render", "--out", str(out), "--count", "1", "--width", "64", "--height", "64",
            "--shapes", "square", "--sizes", "50", "--no-progress"]  # fmt: skip
    assert cli.main(argv) == 0
    before = _files(out)
    assert sorted(before) == ["000000.json", "000000.png", "manifest.json"]
    capsys.readouterr()
    assert cli.main([*argv, "--seed", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("mjx-peg-vision: error: ")
    assert "holds a vision split with a different config (seed: 0 there, 1 now)" in err
    assert "--force" in err and _files(out) == before
    assert cli.main([*argv, "--seed", "1", "--force"]) == 0
    assert "--force: moved the earlier vision split in" in capsys.readouterr().err
    (moved,) = [p for p in tmp_path.iterdir() if p.name.startswith("split.replaced-")]
    assert _files(moved) == before
    assert json.loads((out / "manifest.json").read_text())["config"]["seed"] == 1
    # Growing the split resumes it: only the new image is rendered.
    assert cli.main([*argv[:4], "2", *argv[5:], "--seed", "1"]) == 0
    assert "rendered 1 images (2 in the split)" in capsys.readouterr().out
    # Nothing but a split is moved aside.
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("x\n")
    assert cli.main([*argv[:2], str(mine), *argv[3:], "--force"]) == 2
    assert "--force replaces only a vision split" in capsys.readouterr().err
    assert _files(mine) == {"notes.txt": b"x\n"}
