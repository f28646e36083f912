"""The CPU engine on a Ray cluster (`engines/ray_pool.py`): a local cluster of 2 CPUs started in
the test; grids and training bit-identical to the local run, a worker killed mid-run, one-line
errors, and the CLIs without Ray."""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

ray = pytest.importorskip("ray", reason="the cluster extra is part of the test extra")

from mjx_peg.engines import ray_pool, run_trials  # noqa: E402
from mjx_peg.engines.trial import TrialConfig  # noqa: E402
from mjx_peg.evaluation import eval_cli  # noqa: E402
from mjx_peg.learn import cli as train_cli  # noqa: E402
from mjx_peg.skill.baseline import baseline_params  # noqa: E402
from mjx_peg.world.task import TaskConfig, sample_trials  # noqa: E402

# One local Ray cluster at a time: under pytest-xdist (README's test command, --dist loadgroup)
# these tests run one after another on one worker.
pytestmark = pytest.mark.xdist_group("ray")

EVAL = [
    "--policy", "baseline", "--grid", "custom", "--linear-mm", "1,3", "--angular-deg", "1,4",
    "--trials", "3", "--time-limit", "0.3", "--shape", "square", "--engine", "mujoco",
    "--no-progress",
]  # fmt: skip
TRAIN = ["--trials", "32", "--num-envs", "16", "--time-limit", "0.2", "--no-progress"]


@pytest.fixture(scope="module")
def cluster():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    actors = ray_pool.connect("local")
    yield actors
    ray_pool.shutdown()


def test_a_worker_killed_mid_grid_is_retried_and_the_grid_is_the_local_one(cluster, tmp_path):
    slow = [*EVAL, "--trials", "4", "--time-limit", "2"]  # later flags win
    assert eval_cli.main([*slow, "--processes", "0", "--out", str(tmp_path / "local")]) == 0
    pids = ray.get([a.pid.remote() for a in cluster])
    killed_at = []

    def kill():
        time.sleep(1.0)
        os.kill(pids[0], signal.SIGKILL)
        killed_at.append(time.perf_counter())

    killer = threading.Thread(target=kill)
    killer.start()
    assert eval_cli.main([*slow, "--ray", "--out", str(tmp_path / "ray")]) == 0
    ended = time.perf_counter()
    killer.join()
    assert killed_at and killed_at[0] < ended  # the kill came while the grid ran
    assert ray.get(cluster[0].pid.remote()) != pids[0]  # the actor was restarted
    for name in ("grid.csv", "summary.md"):
        local = (tmp_path / "local" / name).read_bytes()
        assert local == (tmp_path / "ray" / name).read_bytes(), name


def test_the_engine_on_the_cluster_gives_the_local_results(cluster):
    specs = sample_trials(TaskConfig(linear_error=0.003), 1, 9)
    config = TrialConfig(time_limit_s=0.5)
    local = run_trials(specs, baseline_params(), "mujoco", config, threads=1)
    counts = []
    remote = run_trials(
        specs, baseline_params(), "mujoco", config, ray="local", progress=counts.append
    )
    assert sorted(counts) == [4, 5]  # one piece per actor (pieces keep >= MIN_PIECE_TRIALS)
    for field in dataclasses.fields(local):
        np.testing.assert_array_equal(getattr(local, field.name), getattr(remote, field.name))


def test_a_grid_on_the_cluster_is_byte_identical_to_the_local_one(cluster, tmp_path):
    assert eval_cli.main([*EVAL, "--processes", "0", "--out", str(tmp_path / "local")]) == 0
    assert eval_cli.main([*EVAL, "--ray", "--out", str(tmp_path / "ray")]) == 0
    for name in ("grid.csv", "summary.md"):
        local = (tmp_path / "local" / name).read_bytes()
        assert local == (tmp_path / "ray" / name).read_bytes(), name
    ranges = sorted(p.name for p in (tmp_path / "ray" / "ranges").iterdir())
    assert ranges == [f"{i:05d}.npz" for i in range(4)]


def test_training_on_the_cluster_is_bit_identical(cluster, tmp_path):
    assert train_cli.main([*TRAIN, "--out", str(tmp_path / "local")]) == 0
    assert train_cli.main([*TRAIN, "--ray", "--out", str(tmp_path / "ray")]) == 0
    for name in ("trials.csv", "policy.npz"):
        assert (tmp_path / "local" / name).read_bytes() == (tmp_path / "ray" / name).read_bytes()


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--ray", "127.0.0.1:9"], "cannot reach the Ray cluster at 127.0.0.1:9"),
        (["--ray", "nowhere"], "--ray must be auto, local or HOST:PORT, got 'nowhere'"),
        (["--ray", "127.0.0.1:\u00b2"], "--ray must end in a port 1..65535"),
        (["--ray", "127.0.0.1:99999"], "--ray must end in a port 1..65535, got '127.0.0.1:99999'"),
        (["--ray", "--processes", "2"], "--ray runs one lane per cluster CPU: drop --processes"),
    ],
)
def test_bad_cluster_input_is_one_line(extra, message, tmp_path, capsys):
    ray_pool.shutdown()  # left, so that the address is checked (the cluster tests ran above)
    out = tmp_path / "new" / "eval"
    assert eval_cli.main([*EVAL, *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []  # neither --out, its parents nor a lock


def test_without_ray_the_clis_work_and_ray_says_how_to_install(tmp_path):
    code = (
        "import sys\n"
        "from mjx_peg.evaluation import eval_cli as grid\n"
        "argv = sys.argv[2:]\n"
        "assert grid.main([*argv, '--out', sys.argv[1] + '/plain']) == 0\n"
        "assert not [m for m in sys.modules if m.split('.')[0] == 'ray'], 'ray imported'\n"
        "sys.modules['ray'] = None  # as if it were not installed\n"
        "sys.exit(grid.main([*argv, '--ray', '--out', sys.argv[1] + '/ray']))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path), *EVAL, "--processes", "0"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2, done.stderr
    assert 'needs Ray: pip install -e ".[cluster]"' in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
