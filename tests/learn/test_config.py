"""learn/config.py: TrainConfig, its presets, and the config.json of a run (older ones too)."""

import json

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.learn.config import PRESETS, TrainConfig
from mjx_peg.policy import observation
from mjx_peg.world import family
from mjx_peg.world.task import sample_trials


def test_the_default_config_is_the_default_preset():
    assert TrainConfig() == PRESETS["quick"]
    quick = TrainConfig()
    assert (quick.linear_mm, quick.angular_deg, quick.trials, quick.skill) == (
        8.0,
        12.0,
        3584,
        "spiral",
    )
    assert quick.iterations == 14  # 3,584 trials in iterations of 256


def test_each_preset_is_the_default_with_a_budget_or_a_shape_changed():
    default = TrainConfig().to_json()
    changed = {name: {k: v for k, v in p.to_json().items() if default[k] != v}
               for name, p in PRESETS.items()}  # fmt: skip
    assert changed == {
        "quick": {},
        "paper": {"preset": "paper", "trials": 8192},
        "transfer": {
            "preset": "transfer",
            "shapes": ("triangle",),
            "trials": 800,
            "num_envs": 40,
            "learn_search": False,
        },
        "family": {
            "preset": "family",
            "trials": 8192,
            "linear_per_size": True,
            "learn_search": False,
            "parts": tuple((p.shape, p.size_mm, p.hole_scale) for p in family.TRAINED),
            "shapes": ("circle", "square", "triangle", "hexagon", "rectangle"),
            "size_mm": (10.0, 25.0, 30.0, 35.0, 40.0, 50.0, 60.0, 70.0, 80.0),
        },
    }


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_a_config_reads_back_from_its_json(name):
    config = PRESETS[name].replace(seed=7, init_from="runs/x" if name == "transfer" else None)
    assert TrainConfig.from_json(json.loads(config.dumps())) == config


def test_an_older_config_keeps_the_meaning_it_was_written_with():
    """A config.json without the fields it predates, or without the error ranges and budget that
    TrainConfig's defaults held before they became the quick preset's."""
    full = TrainConfig().to_json()
    # fields added since the first runs
    added = ("action_map", "grasp_model", "skill", "skill_constants", "observation")
    defaulted = ("linear_mm", "angular_deg", "trials")  # the former defaults
    old = {k: v for k, v in full.items() if k not in added + defaulted}
    config = TrainConfig.from_json(old)
    assert config.action_map == "sigmoid" and config.grasp_model == "flange"
    assert config.observation == "names" and TrainConfig().observation == "geometry"
    assert (config.skill, config.linear_mm, config.angular_deg, config.trials) == (
        "paper", 4.0, 6.0, 12288,
    )  # fmt: skip
    assert config.task().linear_error == pytest.approx(0.004)
    assert config.trial().search == TrainConfig(skill="paper").trial().search


def test_bad_configs_are_refused_naming_the_field():
    with pytest.raises(UsageError, match=r"unknown fields \['workers'\]"):
        TrainConfig.from_json({**TrainConfig().to_json(), "workers": 2})
    with pytest.raises(UsageError, match="--trials must be a positive integer"):
        TrainConfig(trials=0)
    with pytest.raises(UsageError, match="--num-envs 100 must be a multiple of num_minibatches 3"):
        TrainConfig(num_envs=100, num_minibatches=3)
    with pytest.raises(UsageError, match="unknown shape 'octagon'"):
        TrainConfig(shapes=("circle", "octagon"))
    with pytest.raises(UsageError, match="unknown observation layout 'pixels'"):
        TrainConfig(observation="pixels")
    with pytest.raises(UsageError, match="unknown skill 'search-old'"):
        TrainConfig(skill="search-old")


@pytest.mark.parametrize(
    "config",
    [
        PRESETS["family"],
        TrainConfig(shapes=("hexagon", "rectangle", "triangle"), size_mm=(20.0, 35.0, 70.0)),
        TrainConfig(shapes=("circle",), size_mm=(50.0,), observation="names"),
    ],
    ids=["family", "three-sizes", "names"],
)
def test_the_part_range_spans_exactly_the_parts_a_config_trains_on(config):
    """Every part the task draws lies in the recorded range and each bound is reached."""
    specs = sample_trials(config.task(), 5, 2000)
    seen = observation.part_features(config.observation, specs.shape_id, specs.size,
                                     specs.hole_scale)  # fmt: skip
    low, high = config.part_range()
    assert np.all(seen >= low - 1e-12) and np.all(seen <= high + 1e-12)
    np.testing.assert_allclose(seen.min(axis=0), low, atol=1e-9)
    np.testing.assert_allclose(seen.max(axis=0), high, atol=1e-9)
