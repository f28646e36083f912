"""The family of parts: the suite's parts, a TaskConfig drawing from a list of parts, errors
scaled with each part's size."""

import json

import numpy as np
import pytest

from mjx_peg.learn.config import PRESETS, TrainConfig
from mjx_peg.world import family
from mjx_peg.world.constants import SHAPES
from mjx_peg.world.task import TaskConfig, sample_trials


def test_the_suite_spans_shapes_sizes_and_fits_and_holds_parts_out():
    assert len(family.SUITE) >= 12
    assert {p.shape for p in family.SUITE} == set(SHAPES)
    sizes = [p.size_mm for p in family.SUITE]
    assert min(sizes) == 10 and max(sizes) == 80
    assert {p.fit for p in family.SUITE} == {"paper", "tight"}
    assert [p.name for p in family.HELD_OUT] == [
        "triangle-60-tight", "hexagon-20", "rectangle-70-tight", "square-12"
    ]  # fmt: skip
    assert family.by_name("circle-25-tight").hole_scale == pytest.approx(1.01)
    assert family.by_name("square-12").hole_scale == pytest.approx(1.08)
    with pytest.raises(KeyError, match="no part 'circle-11'"):
        family.by_name("circle-11")


def test_a_list_of_parts_draws_only_its_parts_with_errors_scaled_by_size():
    parts = tuple(p.task_part() for p in family.TRAINED)
    task = TaskConfig.from_mm_deg(("circle",), (50,), 8, 12, parts=parts, linear_per_size=True)
    assert set(task.shapes) == set(SHAPES) and task.sizes[0] == pytest.approx(0.01)
    specs = sample_trials(task, 5, 1500)
    triples = zip(specs.shape_id, specs.size, specs.hole_scale, strict=True)
    drawn = {(SHAPES[i], round(s * 1000, 3), round(h, 3)) for i, s, h in triples}
    assert drawn == {(s, round(z * 1000, 3), round(h, 3)) for s, z, h in parts}
    scale = specs.size / 0.05
    np.testing.assert_allclose(specs.linear_range, 0.008 * scale)
    assert np.all(np.abs(specs.loc_error[:, :2]) <= 0.008 * scale[:, None] + 1e-12)
    small = specs.size == 0.01
    assert np.abs(specs.loc_error[small, :2]).max() > 0.8 * 0.0016  # the range is used
    assert np.abs(specs.loc_error[:, 2]).max() == pytest.approx(np.radians(12), rel=0.01)
    np.testing.assert_allclose(specs.angular_range, np.radians(12))
    assert np.all(np.abs(specs.board_height) <= 0.008 * scale + 1e-12)


def test_the_family_preset_trains_on_the_trained_parts_alone():
    config = PRESETS["family"]
    held = {(p.shape, p.size_mm, p.hole_scale) for p in family.HELD_OUT}
    assert len(config.parts) == len(family.TRAINED) and not held & set(config.parts)
    assert config.linear_per_size and config.task().linear_per_size
    assert config.shapes == tuple(dict.fromkeys(p.shape for p in family.TRAINED))
    assert TrainConfig.from_json(json.loads(config.dumps())) == config
