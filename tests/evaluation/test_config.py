"""evaluation/config.py: an evaluation's config, its grids and the trials of a range."""

import numpy as np
import pytest

from mjx_peg.evaluation import config as eval_config


def test_range_specs_depend_only_on_seed_and_index():
    config = eval_config.EvalConfig(
        "baseline", "custom", (1.0, 4.0), (2.0,), 5, ("circle", "square"), 50.0, 1.0, seed=3
    )
    assert config.shape_counts() == [3, 2]
    a, b = eval_config.range_specs(config, 1), eval_config.range_specs(config, 1)
    np.testing.assert_array_equal(a.loc_error, b.loc_error)
    assert list(a.shape_id) == [0, 0, 0, 1, 1]
    assert np.all(np.abs(a.loc_error[:, :2]) <= 0.004) and np.all(a.linear_range == 0.004)
    other_seed = eval_config.range_specs(config.__class__(**{**config.__dict__, "seed": 4}), 1)
    assert not np.allclose(a.board_pos, other_seed.board_pos)
    # Preset linear ranges scale with S (percent of S/2 in the paper) unless asked not to.
    assert eval_config.grid_axes("paper-small", 25.0)[0][-1] == pytest.approx(4.0)
    assert eval_config.grid_axes("paper-small", 25.0, linear_absolute=True)[0][-1] == 8.0


def test_the_paper_grids():
    """Section 6.2: 350 ranges up to 8 mm / 12 deg, N = 200 (our 25 x 14 split); 6.3-6.5: 100."""
    lin, ang, trials = eval_config.PRESETS["paper"]
    assert (len(lin), len(ang), trials) == (25, 14, 200)
    assert lin[0] == pytest.approx(0.32) and lin[-1] == pytest.approx(8.0)
    assert ang[0] == pytest.approx(12 / 14) and ang[-1] == pytest.approx(12.0)
    lin, ang, trials = eval_config.grid_axes("paper-small", 50.0)
    assert (len(lin), len(ang), trials) == (10, 10, 50) and lin[-1] == 8.0 and ang[-1] == 12.0
    assert eval_config.grid_axes("custom", 50.0, (1.0, 2.0), (3.0,)) == ((1.0, 2.0), (3.0,), None)


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"grid": "huge"}, "unknown grid 'huge'"),
        ({"linear_mm": (1.0, 1.0)}, "linear_mm repeats a value"),
        ({"angular_deg": (50.0,)}, r"angular_deg must lie in \[0, 45\]"),
        ({"trials": 0}, "trials per range must be a positive integer"),
        ({"shapes": ("circle", "circle")}, "shapes must be distinct"),
        ({"engine": "auto"}, "engine must be resolved to mujoco or mjx"),
        ({"skill": "fast"}, "unknown skill 'fast'"),
    ],
)
def test_a_bad_config_is_one_line(changes, message):
    base = dict(policy="baseline", grid="custom", linear_mm=(1.0,), angular_deg=(1.0,), trials=2,
                shapes=("square",), size_mm=50.0)  # fmt: skip
    with pytest.raises(ValueError, match=message) as info:
        eval_config.EvalConfig(**{**base, **changes})
    assert "\n" not in str(info.value)
