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
