"""Each script under experiments/ runs with tiny arguments (so that none can rot)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_fingerprint_runs_and_compares_bit_for_bit(tmp_path):
    script = ROOT / "experiments" / "fingerprint.py"
    first, second = tmp_path / "a.npz", tmp_path / "b.npz"
    tiny = ["--trials", "3", "--time-scale", "0.02"]
    done = subprocess.run([sys.executable, script, first, *tiny], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    done = subprocess.run([sys.executable, script, second, *tiny, "--compare", first],
                          capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert "70 of 70 arrays bit-identical" in done.stdout
