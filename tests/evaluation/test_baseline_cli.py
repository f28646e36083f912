"""evaluation/baseline_cli.py (`mjx-peg-baseline`): one line per shape, the engine's summary of
the baseline on that shape's sampled trials; bad shapes one line."""

from __future__ import annotations

import pytest

from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.evaluation import baseline_cli
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.search import skill_config
from mjx_peg.world.task import TaskConfig, sample_trials


def test_one_line_per_shape_is_the_engines_summary(capsys):
    argv = ["--shapes", "circle,triangle", "--trials", "3", "--time-limit", "0.3", "--seed", "4",
            "--linear-mm", "2", "--angular-deg", "3", "--engine", "mujoco"]  # fmt: skip
    assert baseline_cli.main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    config = TrialConfig(time_limit_s=0.3, search=skill_config("paper"))
    expected = []
    for shape in ("circle", "triangle"):
        specs = sample_trials(TaskConfig.from_mm_deg((shape,), 50.0, 2.0, 3.0), 4, 3)
        result = run_trials(specs, baseline_params(), engine="mujoco", config=config, threads=1)
        assert result.steps.tolist() == [150] * 3  # 0.3 s: none inserted yet
        expected.append(f"{shape} 50 mm ±2 mm ±3 deg: {result.summary()}")
    assert lines == expected


@pytest.mark.parametrize(
    "shapes, message",
    [("octagon", "unknown shape 'octagon': choose from circle, square"),
     (",", "--shapes is empty: choose from circle, square")],
)  # fmt: skip
def test_a_bad_shape_is_one_line(shapes, message, capsys):
    assert baseline_cli.main(["--shapes", shapes]) == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert err.startswith(f"{baseline_cli.PROG}: error: {message}"), err
