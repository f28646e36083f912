"""A full disk is one line naming the file, and leaves nothing half-written that breaks a rerun.

A disk that fills is simulated with a small RLIMIT_FSIZE in a child process (SIGXFSZ ignored):
a write past it fails with EFBIG, as one past a full disk fails with ENOSPC, through the same
code paths (Orbax's tensorstore writes included).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LIMITED = (
    "import resource, signal, sys\n"
    "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
    "SOFT, HARD = resource.getrlimit(resource.RLIMIT_FSIZE)\n"
    "def limit(size):\n"
    "    resource.setrlimit(resource.RLIMIT_FSIZE, (size, HARD))\n"
    "def unlimit():\n"
    "    resource.setrlimit(resource.RLIMIT_FSIZE, (SOFT, HARD))\n"
)


def _python(code: str, *args, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "JAX_PLATFORMS": "cpu"}
    return subprocess.run([sys.executable, "-c", LIMITED + code, *map(str, args)], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=timeout)  # fmt: skip


@pytest.mark.slow
def test_a_checkpoint_that_does_not_fit_is_an_oserror_naming_its_step_and_leaves_nothing(
    tmp_path,
):
    """Orbax's failed writes (a ValueError with tensorstore's status, logged with tracebacks
    from its threads) become one OSError naming the step; the step's partial directory is
    gone, and the same save succeeds once there is room."""
    code = (
        "import os\n"
        "import numpy as np\n"
        "from mjx_peg.learn.checkpoints import Checkpoints\n"
        "tree = {'w': np.random.default_rng(0).normal(size=50_000)}\n"  # 400 kB, incompressible
        "with Checkpoints(sys.argv[1], keep=3) as ckpt:\n"
        "    limit(100_000)\n"
        "    try:\n"
        "        ckpt.save(1, tree)\n"
        "    except OSError as e:\n"
        "        print('OSError', e.filename, e.strerror)\n"
        "    unlimit()\n"
        "    print(sorted(os.listdir(sys.argv[1])))\n"
        "    ckpt.save(1, tree)\n"
        "    print(bool(np.array_equal(ckpt.restore(tree)['w'], tree['w'])))\n"
    )
    done = _python(code, tmp_path / "checkpoints")
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.splitlines() == [
        f"OSError {tmp_path / 'checkpoints' / '1'} File too large",
        "[]",
        "True",
    ]
    assert done.stderr == ""  # Orbax's own reports of the failed writes are held back


@pytest.mark.slow
def test_a_training_table_that_does_not_fit_is_named_and_the_resume_cuts_it_back(tmp_path):
    code = (
        "from mjx_peg.learn.run_dir import RunDir\n"
        "run = RunDir(sys.argv[1]); run.path.mkdir()\n"
        "limit(300)\n"
        "run.start_tables()\n"
        "row = [[k, '1.00', 0, ''] for k in range(8)]\n"
        "run.append([1, 8] + ['0'] * 15, row)\n"
        "try:\n"
        "    run.append([2, 16] + ['0'] * 15, [[8 + k, '1.00', 0, ''] for k in range(40)])\n"
        "except OSError as e:\n"
        "    print('OSError', e.filename, e.strerror)\n"
        "unlimit()\n"
        "run.truncate_tables(8)\n"
        "print(len(run.trials_path.read_text().splitlines()))\n"
    )
    done = _python(code, tmp_path / "run")
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.splitlines() == [f"OSError {tmp_path / 'run' / 'trials.csv'} File too large",
                                        "9"]  # fmt: skip


@pytest.mark.slow
def test_the_robot_cli_on_a_full_disk_is_one_line_and_leaves_nothing_half_written(tmp_path):
    code = (
        "limit(40)\n"  # runs.csv's header is 90 bytes
        "from mjx_peg.robot import cli\n"
        "sys.exit(cli.main(['--trials', '1', '--time-limit', '0.05', '--no-progress',\n"
        "                   '--out', sys.argv[1]]))\n"
    )
    done = _python(code, tmp_path / "out")
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        f"python -m mjx_peg.robot: error: {tmp_path / 'out' / 'skill.json'}: File too large"
    ]  # the first file it writes, skill.json (~600 bytes): named, not half-written
    assert not (tmp_path / "out").exists()  # the folder it made for the run, removed again
