"""vision/act.py: trials whose hole estimate comes from the localizer record the skill they ran."""

import json


def test_act_records_the_skill_it_ran(tmp_path):
    """summary.json records the skill's name and every constant: without a skill, the one the
    policy's manifest names (the shipped `paper`: spiral, with the constants it records)."""
    from mjx_peg.policy.export import load_policy
    from mjx_peg.policy.shipped import SHIPPED_DIR
    from mjx_peg.skill.search import constants_record
    from mjx_peg.vision import act
    from mjx_peg.vision.localizer import Localizer

    loc = Localizer.load(SHIPPED_DIR / "localizer")
    act.run_act(loc, "paper", tmp_path, shapes=("circle",), trials=1, time_limit_s=0.1,
                progress=False)  # fmt: skip
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["skill"] == "spiral"
    assert summary["skill_constants"] == constants_record(load_policy("paper").skill.config)
