"""engines/mjx.py: the accelerator engine's trials end as the C engine's on the same specs
(sim-to-sim), one MJX compile; `experiments/engines_agree.py` runs the comparison."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from mjx_peg.engines.trial import TrialConfig

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_engines_agree(tmp_path, capsys):
    """C MuJoCo and MJX give the same outcomes on the same 40 specs (sim-to-sim check) with the
    shipped skill and policy (the spiral, `paper`'s vectors), run by
    `experiments/engines_agree.py` in this process: the script's smoke test too.

    The bar: the same outcome on at least 90 % of at least 32 trials that end within the limit
    on C MuJoCo, set beside C MuJoCo against itself with every hole moved by 1e-9 m. These 40
    squares (+-3 mm / +-3 deg, seed 52, 4 s; `paper` as shipped 2026-12-07) all insert on both
    engines by 3.2 s, the same outcome on 40 / 40 (the nudge: 40 / 40), the median times 0.977
    against 0.978 s, the tips 0.08 mm apart (median). MJX on this CPU compiles one program per
    scene (~45 s) and then steps the batch in seconds (`engines.mjx.CPU_COMPILER_OPTIONS`);
    alone, empty compilation cache: 61-64 s. The circle's scene: one MJX step in
    tests/world/test_mjcf.py.
    At larger errors more trials part between the engines (`experiments/engines_agree.py
    --trials 48 ...` measures by how much: BENCHMARKS.md). The F/T pipeline itself is the same
    function on both (tests/engines/test_period.py, tests/skill/test_sensor.py); here both
    engines must report peak sensed forces of the same size and chatter of the same size. The
    paper's skill runs the same physics; its control period in JAX is checked against NumPy in
    tests/skill/test_control_step.py and tests/engines/test_compiled.py.
    """
    spec = importlib.util.spec_from_file_location(
        "engines_agree", ROOT / "experiments" / "engines_agree.py"
    )
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    out, limit = tmp_path / "agree.npz", 4.0
    script.main(["--trials", "40", "--time-limit", str(limit), "--batch", "40",
                 "--shapes", "square", "--linear-mm", "3", "--angular-deg", "3", "--seed", "52",
                 "--skill", "spiral", "--policy", "paper", "--out", str(out)])  # fmt: skip
    text = capsys.readouterr().out
    assert "same outcome on" in text and "mujoco vs mujoco with holes moved" in text
    with np.load(out) as saved:
        cpu_ok, acc_ok = saved["mujoco_success"], saved["mjx_success"]
        assert cpu_ok.shape == acc_ok.shape == saved["nudged_success"].shape == (40,)
        ended = saved["mujoco_steps"] < TrialConfig(time_limit_s=limit).max_steps  # on C MuJoCo
        assert ended.sum() >= 32
        same = (cpu_ok == acc_ok)[ended].mean()
        assert same >= 0.9
        assert same >= (cpu_ok == saved["nudged_success"])[ended].mean() - 0.1
        both = cpu_ok & acc_ok
        assert both.sum() >= 28
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
