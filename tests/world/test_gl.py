"""world/gl.py: MUJOCO_GL made a value MuJoCo imports with, in a fresh interpreter each (MuJoCo
reads it once): a usable one kept, an unusable one replaced by a headless back-end with one
line saying so, none chosen without a display."""

from __future__ import annotations

import ctypes
import os
import subprocess
import sys

import pytest


def _loads(*names) -> bool:
    for name in names:
        try:
            ctypes.CDLL(name)
            return True
        except OSError:
            continue
    return False


HEADLESS = ("egl" if _loads("libEGL.so.1", "libEGL.so")
            else "osmesa" if _loads("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so")
            else "disable")  # fmt: skip


def _choose(value: str | None) -> list[str]:
    """[MUJOCO_GL after `import mjx_peg`, choose_backend() again, fallback_note(), is_disabled()]
    in a fresh interpreter without a display."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env.pop("MUJOCO_GL", None)
    if value is not None:
        env["MUJOCO_GL"] = value
    code = (
        "import os\n"
        "from mjx_peg.world import gl\n"
        "print(os.environ['MUJOCO_GL'], gl.choose_backend(), gl.fallback_note(), gl.is_disabled(),"
        " sep='|')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip().split("|")


def test_without_a_display_or_a_choice_rendering_is_headless():
    env, again, note, disabled = _choose(None)
    assert env == again == HEADLESS and disabled == str(HEADLESS == "disable")
    if HEADLESS == "egl":
        assert note == "None"
    else:
        assert note == f"no egl here (libEGL); rendering with {HEADLESS}"


@pytest.mark.parametrize("value", ["disable", "off"])
def test_rendering_disabled_by_choice_is_left_alone(value):
    assert _choose(value) == [value, value, "None", "True"]


@pytest.mark.parametrize(
    "value, why",
    [("bogus", "is not a back-end MuJoCo knows (egl, osmesa, glx, glfw)"),
     ("glfw", "needs a display (DISPLAY is not set)")],
)  # fmt: skip
def test_an_unusable_value_is_replaced_and_said_in_one_line(value, why):
    env, again, note, _ = _choose(value)
    assert env == again == HEADLESS
    if HEADLESS == "disable":
        assert note == f"MUJOCO_GL='{value}' {why}, and neither egl nor osmesa loads here"
    else:
        assert note == f"MUJOCO_GL='{value}' {why}; rendering with {HEADLESS} instead"


def test_a_usable_headless_value_is_kept():
    assert _choose(HEADLESS)[:3] == [HEADLESS, HEADLESS, "None"]
