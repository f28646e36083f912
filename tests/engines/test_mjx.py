"""engines/mjx.py: the accelerator engine's trials end as the C engine's on the same specs
(sim-to-sim), one MJX compile; `experiments/engines_agree.py` runs the comparison."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_engines_agree(tmp_path, capsys):
    """C MuJoCo and MJX give the same outcomes on the same 8 specs (sim-to-sim check) with the
    shipped skill and policy (the spiral, `paper`'s vectors), run by
    `experiments/engines_agree.py` in this process: the script's smoke test too.

    MJX on this CPU compiles one program per scene (~90 s each) and then steps each scene's
    batch, every slot until its last trial ends, at a rate nearly independent of the batch's
    size: one scene, and a batch of trials that all end early, is the cheapest check. These 8
    squares (+-3 mm / +-3 deg, seed 52; `paper` as shipped 2026-12-07) all insert on both
    engines by 1.91 s, every one after contact (peak sensed forces 43-97 N), two of them after
    1.2 s (the chatter metric's trials); the median times agree to the step (0.942 s), the tips
    0.06 mm apart (median). Alone, empty compilation cache: 184 s (the 3 circles and 5 squares
    it ran until 2026-12-07, two scenes: 313 s). The circle's scene: one MJX step in
    tests/world/test_mjcf.py.
    At larger errors more trials part between the engines (`experiments/engines_agree.py
    --trials 48 ...` measures by how much: BENCHMARKS.md). The F/T pipeline itself is the same
    function on both (tests/engines/test_period.py, tests/skill/test_sensor.py); here both
    engines must report peak sensed forces of the same size and chatter of the same size. Most
    of this test's time is the compile (BENCHMARKS.md, "Test suite"). The paper's skill
    runs the same physics; its control period in JAX is checked against NumPy in
    tests/skill/test_control_step.py and tests/engines/test_compiled.py.
    """
    spec = importlib.util.spec_from_file_location(
        "engines_agree", ROOT / "experiments" / "engines_agree.py"
    )
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    out = tmp_path / "agree.npz"
    script.main(["--trials", "8", "--time-limit", "2.5", "--batch", "8", "--shapes", "square",
                 "--linear-mm", "3", "--angular-deg", "3", "--seed", "52", "--skill", "spiral",
                 "--policy", "paper", "--out", str(out)])  # fmt: skip
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
        # chatter (N; mean |dF| over a trial's last second): of the same size, none runaway
        chatter_cpu, chatter_acc = saved["mujoco_chatter"], saved["mjx_chatter"]
        assert abs(np.median(chatter_acc) / np.median(chatter_cpu) - 1.0) < 0.35
        assert np.all(chatter_cpu < 10.0) and np.all(chatter_acc < 10.0)
