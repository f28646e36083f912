"""skill/skill_cli.py: --skill-constant NAME=VALUE read into (name, value), bad text refused."""

import argparse

import pytest

from mjx_peg.skill.skill_cli import skill_constant


def test_a_constant_is_read_as_its_name_and_value():
    assert skill_constant("spiral_yaw=0.1") == ("spiral_yaw", 0.1)
    assert skill_constant(" spiral_yaw_period = 1 ") == ("spiral_yaw_period", 1.0)
    assert skill_constant("search_budget=inf") == ("search_budget", float("inf"))
    assert skill_constant("part_scale=size") == ("part_scale", "size")  # a constant that is a name


@pytest.mark.parametrize(
    "text, message",
    [
        ("bogus=1", "NAME a constant of the skill"),
        ("spiral_yaw", "NAME a constant of the skill"),
        ("spiral_yaw=wide", "spiral_yaw must be a number, got 'wide'"),
    ],
)
def test_anything_else_is_refused_with_what_it_takes(text, message):
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        skill_constant(text)
