"""Where MuJoCo's own warnings go: the command's output directory, or nowhere.

By default MuJoCo prints every warning (a blown-up simulation, a near-singular inertia) and
appends it to MUJOCO_LOG.TXT in the working directory. A CLI calls `send_to(out_dir)` (or
`send_to(None)`: nowhere) once it knows its output directory; the choice travels to the engine's
worker processes in the environment (`ENV`), where the engine calls `install()` after importing
MuJoCo. Only the messages move: MuJoCo still counts each warning in MjData.warning and still
resets a diverging simulation, which is how the engine marks such a trial as failed (unstable).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

ENV = "MJX_PEG_MUJOCO_LOG"  # path of the log file; empty: nowhere; unset: MuJoCo's default
FILE = "MUJOCO_LOG.TXT"


def _write(message: str) -> None:
    path = os.environ.get(ENV)
    if not path:
        return
    try:
        with open(path, "a") as f:
            f.write(f"WARNING {time.ctime()}: {message}\n")
    except OSError:
        pass  # a warning must never break a simulation


def install() -> None:
    """Route this process's MuJoCo warnings as `ENV` says (nothing to do when it is unset)."""
    if ENV not in os.environ:
        return
    import mujoco

    mujoco.set_mju_user_warning(_write)


def send_to(directory) -> Path | None:
    """MuJoCo warnings of this process and its engine workers go to DIRECTORY/MUJOCO_LOG.TXT
    (created on the first warning), or nowhere when `directory` is None; returns the path."""
    path = None if directory is None else Path(directory).absolute() / FILE
    os.environ[ENV] = "" if path is None else str(path)
    install()
    return path
