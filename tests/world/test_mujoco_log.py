"""world/mujoco_log.py: MuJoCo's warnings of a process go to the file `send_to` names, created on
the first warning, or nowhere; the simulation still counts and resets as MuJoCo does."""

from __future__ import annotations

import os
import subprocess
import sys

# A free body launched at 1e300 m/s: MuJoCo warns (bad qvel) and resets the simulation.
CODE = (
    "import sys, mujoco\n"
    "from mjx_peg.world import mujoco_log\n"
    "target = None if sys.argv[1] == '-' else sys.argv[1]\n"
    "path = mujoco_log.send_to(target)\n"
    "print(path, mujoco_log.ENV in __import__('os').environ)\n"
    "m = mujoco.MjModel.from_xml_string("
    "'<mujoco><worldbody><body><freejoint/><geom size=\"1\"/></body></worldbody></mujoco>')\n"
    "d = mujoco.MjData(m)\n"
    "d.qvel[0] = 1e300\n"
    "mujoco.mj_step(m, d)\n"
    "print(d.warning[mujoco.mjtWarning.mjWARN_BADQVEL].number, d.time, abs(d.qvel[0]))\n"
)


def _run(target, cwd):
    env = {k: v for k, v in os.environ.items() if k != "MJX_PEG_MUJOCO_LOG"}
    return subprocess.run([sys.executable, "-c", CODE, target], capture_output=True, text=True,
                          cwd=cwd, env=env)  # fmt: skip


def test_warnings_go_to_the_named_directory(tmp_path):
    (tmp_path / "cwd" / "out").mkdir(parents=True)  # a command's --out, made before its work
    done = _run("out", cwd=tmp_path / "cwd")  # a relative directory: made absolute
    assert done.returncode == 0, done.stderr
    log = tmp_path / "cwd" / "out" / "MUJOCO_LOG.TXT"
    assert done.stdout.splitlines() == [f"{log} True", "1 0.002 0.0"]  # counted; reset, then a step
    lines = log.read_text().splitlines()
    assert len(lines) == 1 and lines[0].startswith("WARNING ")
    assert "Nan, Inf or huge value in QVEL" in lines[0]
    assert sorted(p.name for p in (tmp_path / "cwd").iterdir()) == ["out"]


def test_warnings_sent_nowhere_leave_no_file(tmp_path):
    done = _run("-", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["None True", "1 0.002 0.0"] and done.stderr == ""
    assert list(tmp_path.iterdir()) == []
