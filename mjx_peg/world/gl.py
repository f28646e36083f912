"""MuJoCo's OpenGL back-end, chosen in one place: call `choose_backend()` before `import mujoco`.

MuJoCo reads MUJOCO_GL once, when it is first imported. Without a display we default to `egl`
(headless; Mesa provides it on a CPU-only machine). Set MUJOCO_GL yourself (e.g. `osmesa`) before
the first import to choose another back-end.
"""

from __future__ import annotations

import os

HEADLESS_BACKEND = "egl"


def choose_backend() -> str:
    """Set MUJOCO_GL to the headless default unless the user chose one or a display exists."""
    if "MUJOCO_GL" not in os.environ and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        os.environ["MUJOCO_GL"] = HEADLESS_BACKEND
    return os.environ.get("MUJOCO_GL", "")
