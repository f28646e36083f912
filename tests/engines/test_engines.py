"""engines/__init__.py: `run_trials` on either engine; C MuJoCo and MJX agree (sim-to-sim)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from mjx_peg.engines import engine_runner, mujoco, run_trials
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials

ROOT = Path(__file__).resolve().parents[2]


def _specs(shape, n, seed, **errors):
    config = TaskConfig(shapes=(shape,), sizes=(0.05,), **errors)
    return sample_trials(config, seed, n)


def test_bad_input_is_one_clear_error():
    specs = _specs("square", 2, seed=4)
    with pytest.raises(ValueError, match="unknown engine"):
        run_trials(specs, baseline_params(), engine="bullet")
    bad = baseline_params().copy()
    bad[5] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        run_trials(specs, bad, engine="mujoco")
    with pytest.raises(ValueError, match="shape"):
        run_trials(specs, np.zeros(37), engine="mujoco")
    with pytest.raises(ValueError):
        run_trials("not specs", baseline_params(), engine="mujoco")


@pytest.mark.slow
def test_engines_agree(tmp_path, capsys):
    """C MuJoCo and MJX give the same outcomes on the same 8 specs (sim-to-sim check), run by
    `experiments/engines_agree.py` in this process: the script's smoke test too, one MJX compile.

    MJX on this CPU compiles in about 40 s and then steps the whole batch, every slot until the
    last trial ends, at about 8 batch steps/s whatever the batch's size: one batch of trials
    that all end early is the cheapest check. Under the board model these 8 insert on the C
    engine at 1.38-1.42 s (the 2 s limit is headroom).
    At larger errors contact-heavy trials part between the engines (`experiments/engines_agree.py`
    with more trials measures by how much). The F/T pipeline itself is the same function on
    both (tests/engines/test_period.py, tests/skill/test_sensor.py); here both engines must
    report a peak sensed force of the same size.
    """
    spec = importlib.util.spec_from_file_location(
        "engines_agree", ROOT / "experiments" / "engines_agree.py"
    )
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    out = tmp_path / "agree.npz"
    script.main(["--trials", "8", "--time-limit", "2", "--batch", "8", "--shapes", "square",
                 "--linear-mm", "1.5", "--angular-deg", "2", "--seed", "2",
                 "--out", str(out)])  # fmt: skip
    text = capsys.readouterr().out
    assert "same outcome on" in text and "mujoco vs mujoco with holes moved" in text
    with np.load(out) as saved:
        cpu_ok, acc_ok = saved["mujoco_success"], saved["mjx_success"]
        assert cpu_ok.shape == acc_ok.shape == (8,)
        assert (cpu_ok == acc_ok).mean() >= 7 / 8
        both = cpu_ok & acc_ok
        assert both.sum() >= 3
        ratio = np.median(saved["mjx_time_s"][both]) / np.median(saved["mujoco_time_s"][both])
        assert abs(ratio - 1.0) < 0.1
        assert not saved["mjx_unstable"].any()
        peak_cpu, peak_acc = saved["mujoco_peak_force"], saved["mjx_peak_force"]
        assert np.all(peak_cpu > 1.0) and np.all(peak_acc > 1.0)
        assert abs(np.median(peak_acc) / np.median(peak_cpu) - 1.0) < 0.25
        assert np.all(saved["mjx_chatter"] < 5.0) and np.all(saved["mujoco_chatter"] < 5.0)


def test_each_engine_has_its_runner():
    assert engine_runner("mujoco") is mujoco.run_on_cpu
    with pytest.raises(ValueError, match="unknown engine 'auto': choose mujoco or mjx"):
        engine_runner("auto")  # resolved first (resolve_engine)
