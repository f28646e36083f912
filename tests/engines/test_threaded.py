"""engines/threaded.py: the lanes of this process as threads, and the pass a call names."""

import numpy as np
import pytest

from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines import threaded
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.errors import UsageError
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials

CONFIG = TrialConfig(time_limit_s=1.0)


def _specs(n, seed):
    return sample_trials(TaskConfig(shapes=("square",), sizes=(0.05,)), seed, n)


def _params(n):
    return as_controller_params(np.asarray(baseline_params()), n)


def test_an_observer_needs_one_thread():
    with pytest.raises(UsageError, match="an observer runs in the lane's thread"):
        threaded.run_in_threads(_specs(2, 8), _params(2), CONFIG, threads=2,
                                observer=lambda *a: None)  # fmt: skip


def test_a_call_that_names_no_pass_runs_the_compiled_one_end_to_end(monkeypatch):
    """Without MJX_PEG_CONTROL_PASS, run_trials' lanes are compiled (`compiled.CompiledLane`),
    its results those of compiled=True bit for bit."""
    from mjx_peg.engines import run_trials
    from mjx_peg.engines.compiled import CompiledLane

    monkeypatch.delenv(threaded.PASS_VARIABLE, raising=False)
    specs, params, lanes_seen = _specs(2, 3), _params(2), set()
    seen = lambda lane, rows, wrench: lanes_seen.add(type(lane))  # noqa: E731
    default = run_trials(specs, params, "mujoco", CONFIG, threads=1, observer=seen)
    assert lanes_seen == {CompiledLane}
    compiled = cpu_engine.run_on_cpu(specs, params, CONFIG, threads=1, compiled=True)
    assert default.steps.min() > 100  # the trials ran
    for name, value in compiled.to_arrays().items():
        np.testing.assert_array_equal(getattr(default, name), value, err_msg=name)


def test_the_pass_is_named_by_the_call_or_the_environment(monkeypatch):
    """compiled=True/False, or MJX_PEG_CONTROL_PASS (compiled by default); anything else is one
    clear error before a trial runs."""
    with pytest.raises(UsageError, match="compiled must be True or False"):
        cpu_engine.run_on_cpu(_specs(1, 0), _params(1), CONFIG, compiled="yes")
    monkeypatch.setenv(threaded.PASS_VARIABLE, "fast")
    with pytest.raises(UsageError, match="MJX_PEG_CONTROL_PASS must be one of compiled, numpy"):
        cpu_engine.run_on_cpu(_specs(1, 0), _params(1), CONFIG)
    monkeypatch.delenv(threaded.PASS_VARIABLE)
    assert threaded.default_compiled()
    monkeypatch.setenv(threaded.PASS_VARIABLE, "numpy")
    assert not threaded.default_compiled()
