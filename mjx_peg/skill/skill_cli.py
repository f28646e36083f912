"""The skill's command-line types: `--skill-constant NAME=VALUE` as train.py, eval.py, the arm,
the parts suite and the UR5e table take it (`mjx_peg.cli.add_skill_constant_option`)."""

from __future__ import annotations

import argparse
import dataclasses

from mjx_peg import cli
from mjx_peg.skill.search import TEXT_CONSTANTS, SkillConfig


def skill_constant(text: str) -> tuple[str, float | str]:
    """argparse type of --skill-constant: (name, value) of NAME=VALUE, a SkillConfig field and
    a number (a name for the constants that are names)."""
    name, sep, value = str(text).partition("=")
    name, value = name.strip(), value.strip()
    fields = [f.name for f in dataclasses.fields(SkillConfig)]
    if not sep or name not in fields:
        raise argparse.ArgumentTypeError(
            f"must be NAME=VALUE with NAME a constant of the skill ({', '.join(fields)}), got "
            f"{cli.shown(text)}"
        )
    if name in TEXT_CONSTANTS:
        return name, value
    try:
        return name, float(value)
    except ValueError:
        got = cli.shown(value)
        raise argparse.ArgumentTypeError(f"{name} must be a number, got {got}") from None
