"""engines/mjx.py: the accelerator engine's trials end as the C engine's on the same specs
(sim-to-sim), one MJX compile; `experiments/engines_agree.py` runs the comparison."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


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
