"""The policies shipped with the repository (`policies/NAME/`), named on every `--policy`.

`policies/` sits beside the package in the checkout: `quick`, `paper` and `transfer` are the
trained runs the README's tables come from, each a policy.npz + manifest.json with a
`provenance.json` saying which commit and command made it. A `--policy` value is, in order:
"baseline" (the hand-tuned 38 numbers), a path that exists, or the name of a shipped policy.
No JAX here: the robot runtime resolves names too.
"""

from __future__ import annotations

import os
from pathlib import Path

from mjx_peg.errors import UsageError, shown_path

SHIPPED_DIR = Path(__file__).resolve().parents[2] / "policies"


def shipped_names() -> list[str]:
    """The names of the policies under SHIPPED_DIR (directories holding a manifest.json)."""
    if not SHIPPED_DIR.is_dir():
        return []
    return sorted(p.name for p in SHIPPED_DIR.iterdir() if (p / "manifest.json").is_file())


def resolve_policy(policy, flag: str = "--policy", baseline: bool = True) -> str:
    """`policy` as a path to load ("baseline" stays as it is where `baseline`): an existing path
    as given, else the shipped policy of that name (relative to the working directory where it
    lies below it). UsageError (one line naming `flag` and the shipped ones) if it is neither."""
    text = str(policy)
    shown = shown_path(text)
    try:
        exists = Path(text).exists()
    except (OSError, ValueError) as e:  # a name too long, a NUL character
        why = getattr(e, "strerror", None) or str(e)
        raise UsageError(f"{flag} {shown}: cannot be a path ({why})") from None
    if (baseline and text == "baseline") or exists:
        return text
    if text in shipped_names():
        path = SHIPPED_DIR / text
        relative = os.path.relpath(path)
        return path.as_posix() if relative.startswith("..") else relative
    names = ", ".join(shipped_names()) or f"none: {SHIPPED_DIR} is absent"
    raise UsageError(
        f"{flag} {shown}: no such run directory, and no shipped policy of that name "
        f"(shipped: {names}{'; or baseline' if baseline else ''})"
    )


__all__ = ["SHIPPED_DIR", "resolve_policy", "shipped_names"]
