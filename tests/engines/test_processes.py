"""engines/processes.py: the CPU engine's lanes in worker processes give the in-process results,
bit for bit; shards interleave and merge back in spec order; a dead worker is one error."""

import os
import time

import numpy as np
import pytest

from mjx_peg.engines import mujoco as mujoco_engine
from mjx_peg.engines import processes
from mjx_peg.engines.trial import TrialConfig, TrialResult, as_controller_params
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials


def test_shards_interleave_and_merge_back_in_spec_order():
    shards = processes.interleaved(7, 3)
    assert [list(s) for s in shards] == [[0, 3, 6], [1, 4], [2, 5]]
    assert [list(s) for s in processes.interleaved(2, 4)] == [[0], [1]]  # no empty shard
    n = 7
    full = TrialResult(
        success=np.arange(n) % 2 == 0, time_s=np.arange(n) * 0.5,
        final_tip_pos=np.arange(3 * n, dtype=float).reshape(n, 3), peak_force=np.arange(n) * 2.0,
        reward=np.arange(n) * 10.0, unstable=np.zeros(n, bool), steps=np.arange(n) * 3,
        settled=np.arange(n) == 4, chatter=np.arange(n) * 0.1, protective_stop=np.arange(n) == 5,
    )  # fmt: skip
    parts = [TrialResult.from_arrays({k: v[rows] for k, v in full.to_arrays().items()})
             for rows in shards]  # fmt: skip
    merged = processes.merge(n, shards, parts)
    for name, value in full.to_arrays().items():
        np.testing.assert_array_equal(getattr(merged, name), value, err_msg=name)
        assert getattr(merged, name).dtype == value.dtype
    params = as_controller_params(
        np.tile(baseline_params(), (n, 1)) * np.arange(1, n + 1)[:, None], n
    )
    taken = processes.take_params(params, shards[1])
    np.testing.assert_array_equal(np.asarray(taken.k_t), np.asarray(params.k_t)[[1, 4]])


def test_worker_processes_give_the_in_process_results():
    """processes=2: the same results, bit for bit, and every trial reported to progress; bad
    options are one error before any process starts."""
    task = TaskConfig(shapes=("square", "circle"), linear_error=0.003, angular_error=0.07)
    specs = sample_trials(task, 3, 12)
    params = as_controller_params(baseline_params(), len(specs))
    config = TrialConfig(time_limit_s=1.0)
    here = mujoco_engine.run_on_cpu(specs, params, config, threads=1)
    counts = []
    there = mujoco_engine.run_on_cpu(specs, params, config, processes=2, progress=counts.append)
    for name, value in here.to_arrays().items():
        np.testing.assert_array_equal(getattr(there, name), value, err_msg=name)
    assert sum(counts) == len(specs)
    with pytest.raises(ValueError, match="slots_per_thread must be a positive integer"):
        mujoco_engine.run_on_cpu(specs, params, config, processes=2, slots_per_thread=0)


def test_a_dead_worker_process_is_one_clear_error():
    """A worker killed mid-call (as a crash in C would): RuntimeError, not a hang."""
    import multiprocessing
    import signal
    import threading

    specs = sample_trials(TaskConfig(shapes=("square",)), 1, 4)
    params = np.tile(baseline_params(), (4, 1))
    params[:, 0] = 1e-6  # no stiffness: every trial hovers to the time limit
    params = as_controller_params(params, 4)

    def kill_a_worker():
        for _ in range(400):
            workers = multiprocessing.active_children()  # the pool's worker processes
            if workers:
                os.kill(workers[0].pid, signal.SIGKILL)
                return
            time.sleep(0.05)

    threading.Thread(target=kill_a_worker, daemon=True).start()
    start = time.monotonic()
    with pytest.raises(RuntimeError, match="worker process of the CPU engine died"):
        mujoco_engine.run_on_cpu(specs, params, TrialConfig(time_limit_s=600.0), processes=2)
    assert time.monotonic() - start < 60.0


def test_workers_are_spawned_with_sigint_blocked_in_a_fresh_process():
    """The queues' first semaphore starts multiprocessing's resource tracker, which unblocks
    SIGINT when it is started: in a fresh interpreter (no tracker yet) SIGINT is still blocked
    after the pool and its queues are made, where its workers are spawned."""
    import subprocess
    import sys

    code = (
        "import signal\n"
        "from mjx_peg.engines import processes\n"
        "with processes._while_workers_start():\n"
        "    processes._executor(1)\n"
        "    print(signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, []))\n"
        "print(signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, []))\n"
        "processes.shutdown()\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.split() == ["True", "False"]
