"""world/gl.py: MUJOCO_GL made a value MuJoCo imports with, in a fresh interpreter each (MuJoCo
reads it once): a usable one kept, an unusable one replaced by a headless back-end with one
line saying so, the headless one where none is set and there is no display."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

# The suite renders with egl (tests/conftest.py, tests/world/test_render.py): libEGL loads here,
# so egl is the headless back-end choose_backend falls back to.
HEADLESS = "egl"


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
    assert [env, again, note, disabled] == [HEADLESS, HEADLESS, "None", "False"]


@pytest.mark.parametrize("value", ["disable", "off"])
def test_rendering_disabled_by_choice_is_left_alone(value):
    assert _choose(value) == [value, value, "None", "True"]


@pytest.mark.parametrize(
    "value, why",
    [("bogus", "is not a back-end MuJoCo knows (egl, osmesa, glx, glfw)"),
     ("glfw", "needs a display (DISPLAY is not set)")],
)  # fmt: skip
def test_an_unusable_value_is_replaced_and_said_in_one_line(value, why):
    note = f"MUJOCO_GL='{value}' {why}; rendering with {HEADLESS} instead"
    assert _choose(value) == [HEADLESS, HEADLESS, note, "False"]


def test_a_usable_headless_value_is_kept():
    assert _choose(HEADLESS)[:3] == [HEADLESS, HEADLESS, "None"]
