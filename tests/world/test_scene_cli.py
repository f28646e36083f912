"""world/scene_cli.py (`mjx-peg-scene`): the XML and the PNG of a scene; one-line errors."""

import os
import subprocess
import sys

import mujoco
import pytest


def _run_cli(*args, cwd):
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    return subprocess.run(
        [sys.executable, "-m", "mjx_peg.world.scene_cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
        timeout=120,
    )


def test_cli_writes_xml_and_png(tmp_path):
    from matplotlib import image

    out = tmp_path / "tmp"
    proc = _run_cli(
        "--shape",
        "triangle",
        "--size",
        "25",
        "--out",
        str(out),
        "--width",
        "320",
        "--height",
        "240",
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    xml, png = out / "scene_triangle_25mm.xml", out / "scene_triangle_25mm.png"
    assert xml.stat().st_size > 0 and png.stat().st_size > 0
    model = mujoco.MjModel.from_xml_path(str(xml))  # the written XML stands alone
    assert model.nv == 6
    img = image.imread(png)
    assert img.shape[:2] == (240, 320)
    assert img[..., :3].reshape(-1, 3).std(axis=0).max() > 0.05  # not one colour


@pytest.mark.parametrize(
    "args",
    [
        ("--shape", "octagon", "--size", "25"),
        ("--shape", "circle", "--size", "-3"),
        ("--shape", "circle", "--size", "abc"),
    ],
)
def test_cli_bad_input_one_line_no_traceback(tmp_path, args):
    proc = _run_cli(*args, "--out", str(tmp_path / "o"), cwd=tmp_path)
    assert proc.returncode == 2
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "error" in lines[0] and "Traceback" not in proc.stderr, proc.stderr
