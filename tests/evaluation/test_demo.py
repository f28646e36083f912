"""evaluation/demo.py: the watched trial is the engine's trial, its trace one row per control
period, its snapshots every 0.25 s, drawn as a plot and a strip of frames of their size."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib import image

from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.evaluation.demo import frame_strip, plot_trial, run_demo
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials

SPECS = sample_trials(TaskConfig.from_mm_deg(("square",), 50.0, 2.0, 3.0), 5, 1)
CONFIG = TrialConfig(time_limit_s=0.6)


@pytest.fixture(scope="module")
def run():
    return run_demo(SPECS, baseline_params()[None], CONFIG, frames=4)


def test_the_demo_runs_the_engines_trial_and_records_every_period(run):
    engine = cpu_engine.run_on_cpu(SPECS, as_controller_params(baseline_params(), 1), CONFIG,
                                   threads=1)  # fmt: skip
    result = run["result"]
    assert result.steps[0] == engine.steps[0] == 300  # 0.6 s of 2 ms periods, not inserted
    assert result.success[0] == engine.success[0]
    np.testing.assert_array_equal(result.final_tip_pos, engine.final_tip_pos)
    trace = run["trace"]
    assert trace["t"].shape == (300,) and trace["tip"].shape == (300, 3)
    assert trace["wrench"].shape == (300, 6)
    np.testing.assert_allclose(np.diff(trace["t"]), 0.002, atol=1e-12)
    assert np.abs(trace["tip"][-1] - result.final_tip_pos[0]).max() < 1e-3  # one period apart
    times = [t for t, _ in run["snapshots"]]
    np.testing.assert_allclose(times, [trace["t"][0], 0.25, 0.5, trace["t"][-1]], atol=1e-12)
    assert all(qpos.shape == (6,) for _, qpos in run["snapshots"])


def test_the_plot_and_the_strip_are_drawn_at_their_size(run, tmp_path):
    plot_trial(run, tmp_path / "trial.png")
    assert image.imread(tmp_path / "trial.png").shape[:2] == (770, 770)  # 7 x 7 in at 110 dpi
    strip = frame_strip(run, 3)
    assert strip.shape == (320, 960, 3) and strip.dtype == np.uint8  # 3 of the 4 snapshots
    assert frame_strip(dict(run, snapshots=[]), 3) is None
