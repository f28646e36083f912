"""MuJoCo's OpenGL back-end, chosen in one place: `choose_backend()` runs before `import mujoco`.

MuJoCo reads MUJOCO_GL once, when it is first imported, and `import mujoco` itself fails for a
value it does not know (RuntimeError) or for `osmesa` without libOSMesa. So `import mjx_peg`
calls `choose_backend()` (and so does every module that imports MuJoCo), which leaves a usable
value alone and replaces an unusable one with a headless back-end that loads here (`egl`, else
`osmesa`, else `disable`): commands that never render are unaffected, and commands that render
say what happened in one line (`fallback_note()`). Without a display and without MUJOCO_GL we
default to `egl` (headless; Mesa provides it on a CPU-only machine). Set MUJOCO_GL yourself
(e.g. `osmesa`) before the first import to choose another back-end.
"""

from __future__ import annotations

import ctypes
import os
import sys

HEADLESS_BACKEND = "egl"
DISABLED = ("disable", "disabled", "off", "false", "0")
_NEEDS_DISPLAY = ("glfw", "glx", "enable", "enabled", "on", "true", "1")
_KNOWN = {
    "linux": ("egl", "osmesa", "glx", "glfw", "enable", "enabled", "on", "true", "1"),
    "win32": ("wgl", "glfw", "enable", "enabled", "on", "true", "1"),
    "darwin": ("cgl", "glfw", "enable", "enabled", "on", "true", "1"),
}
# Shared libraries PyOpenGL loads for each headless back-end (sonames, newest first).
_LIBRARIES = {
    "egl": ("libEGL.so.1", "libEGL.so"),
    "osmesa": ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so"),
}
_note: str | None = None  # what choose_backend replaced, for commands that render


def _loads(backend: str) -> bool:
    for name in _LIBRARIES.get(backend, ()):
        try:
            ctypes.CDLL(name)
            return True
        except OSError:
            continue
    return False


def _has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _problem(value: str) -> str | None:
    """Why MuJoCo cannot render with MUJOCO_GL=value here, or None if it may."""
    if value in DISABLED:
        return None  # the user's choice: importing works, rendering says it is disabled
    known = _KNOWN.get(sys.platform, ())
    if known and value not in known:
        return f"is not a back-end MuJoCo knows ({', '.join(known[:4])})"
    if value in _LIBRARIES and sys.platform.startswith("linux") and not _loads(value):
        return f"needs {_LIBRARIES[value][0]}, which is not installed"
    if value in _NEEDS_DISPLAY and sys.platform.startswith("linux") and not _has_display():
        return "needs a display (DISPLAY is not set)"
    return None


def _headless() -> str:
    for backend in ("egl", "osmesa"):
        if _loads(backend):
            return backend
    return "disable"


def choose_backend() -> str:
    """Make MUJOCO_GL a value MuJoCo imports with and, where possible, renders with; returns it.

    Unset (or empty) without a display: the headless default. Unusable: a headless back-end that
    loads here, and `fallback_note()` says so. Idempotent: later calls see the replaced value.
    """
    global _note
    raw = os.environ.get("MUJOCO_GL")
    value = (raw or "").strip().lower()
    if not value:
        if _has_display():
            return raw or ""  # MuJoCo's own default (glfw) with the display
        chosen = HEADLESS_BACKEND if _loads(HEADLESS_BACKEND) else _headless()
        if chosen != HEADLESS_BACKEND and _note is None:
            _note = f"no {HEADLESS_BACKEND} here (libEGL); rendering with {chosen}"
        os.environ["MUJOCO_GL"] = chosen
        return chosen
    problem = _problem(value)
    if problem is None:
        return raw
    chosen = _headless()
    os.environ["MUJOCO_GL"] = chosen
    _note = f"MUJOCO_GL={raw!r} {problem}; rendering with {chosen} instead"
    if chosen == "disable":
        _note = f"MUJOCO_GL={raw!r} {problem}, and neither egl nor osmesa loads here"
    return chosen


def fallback_note() -> str | None:
    """What `choose_backend` replaced (one line), or None: printed by commands that render."""
    return _note


def is_disabled() -> bool:
    return os.environ.get("MUJOCO_GL", "").strip().lower() in DISABLED
