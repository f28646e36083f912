"""The skills behind the shipped one, by name: ablations for experiments, not CLI choices.

    from ablations import ablation   # experiments/ablations.py
    TrialConfig(search=ablation("align"))

    paper   the paper's compliant DMP as written (skill.search.SKILLS["paper"])
    search  its contact search's centring alone: the goal moved away from the centre of pressure
            of a peg resting on the board top (docs/design/rim_escape.md)
    align   the centring, and the goal's rotation following the moment the peg feels, its tilt
            once the tcp is 20 mm below the hole's estimated entrance (docs/design/tilted_hole.md)
    spiral  the shipped skill (skill.search.SKILLS["spiral"]): the alignment, the spiral, the
            insertion press, the faster movement and the search's budget (skill/search.py)

`search` and `align` are the constants that files of earlier versions mean by those names
(`file_versions.FORMER_SKILLS`); the scripts that take `--skill` take these names.
"""

from __future__ import annotations

import argparse

from mjx_peg import cli
from mjx_peg.policy.export import policy_skill
from mjx_peg.skill.search import SKILL_DESCRIPTIONS, NamedSkill, SkillConfig, named_skill

DESCRIPTIONS = {
    "paper": SKILL_DESCRIPTIONS["paper"],
    "search": "the contact search's centring alone",
    "align": "the centring and the alignment",
    "spiral": "the shipped skill",
}
ABLATIONS = {name: named_skill(name).config for name in DESCRIPTIONS}


def ablation(name: str) -> SkillConfig:
    """The SkillConfig of an ablation (`ABLATIONS`); SystemExit naming them if unknown."""
    if name not in ABLATIONS:
        raise SystemExit(f"unknown skill {name!r}: choose one of {', '.join(ABLATIONS)}")
    return ABLATIONS[name]


def add_skill_option(parser: argparse.ArgumentParser) -> None:
    """--skill: an ablation's name; default: the policy's skill."""
    cli.add_skill_option(parser, DESCRIPTIONS)


def chosen(name: str | None, policy) -> NamedSkill:
    """The ablation `name`, or the skill `policy` runs unless told otherwise (`policy_skill`)."""
    return policy_skill(policy) if name is None else NamedSkill(name, ablation(name))
