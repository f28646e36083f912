"""Trials in physics: the baseline inserts, bad physics stays contained, the engines agree."""

import importlib.util
import os
import time
from pathlib import Path

import numpy as np
import pytest

from mjx_peg.engines import mujoco as mujoco_engine
from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TaskConfig, sample_trials

ROOT = Path(__file__).resolve().parents[2]
NO_ERRORS = dict(linear_error=0.0, angular_error=0.0)


def _specs(shape, n, seed, **errors):
    config = TaskConfig(shapes=(shape,), sizes=(0.05,), **errors)
    return sample_trials(config, seed, n)


@pytest.mark.parametrize("shape", ["circle", "square", "triangle"])
def test_baseline_inserts_without_errors(shape):
    """No localization or grasp error, the nominal sensor: every trial inserts once the
    compliance ignores the sensor's residual bias (a dead band of 2 N and 0.4 N m). Without
    it the bias alone, +-1 N and +-0.1 N m, shifts the baseline's goal by up to ~2 mm through its
    compliance, more than the circle's 0.75 mm clearance (60 trials of seed 7: circle 90 %,
    triangle 81.7 %; docs/zero_error.md)."""
    specs = _specs(shape, 100, seed=1, **NO_ERRORS)
    config = TrialConfig(force_deadband=2.0, moment_deadband=0.4)
    result = run_trials(specs, baseline_params(), engine="mujoco", config=config)
    print(shape, result.summary())
    assert result.success.all(), result.summary()
    assert np.percentile(result.peak_force, 99) < 10.0  # no hard landing on the rim
    assert np.median(result.time_s[result.success]) < 4.0, result.summary()
    assert not result.unstable.any()
    # Success means the tip is near the table, inside the hole's footprint.
    tips = result.final_tip_pos[result.success]
    assert np.all(tips[:, 2] < 0.02)
    lateral = np.linalg.norm(tips[:, :2] - specs.board_pos[result.success], axis=1)
    assert np.all(lateral < 0.05)
    assert np.all(result.reward[result.success] == 38000.0)


def test_unstable_parameters_fail_alone():
    """Huge gains blow up their own trials; the other trials of the batch are unaffected."""
    specs = _specs("square", 8, seed=2, linear_error=0.002, angular_error=np.deg2rad(2.0))
    good = np.tile(baseline_params(), (8, 1))
    config = TrialConfig(time_limit_s=3.0)
    alone = run_trials(specs, good, engine="mujoco", config=config, threads=1, slots_per_thread=8)
    wild = good.copy()
    wild[1::2, 0] = 1e9  # k_t: stiffness far beyond anything a 2 ms step can integrate
    wild[1::2, 1] = 1e9
    mixed = run_trials(specs, wild, engine="mujoco", config=config, threads=1, slots_per_thread=8)
    assert mixed.unstable[1::2].all()
    assert not mixed.success[1::2].any()
    assert np.all(mixed.reward[1::2] < 38000.0)
    np.testing.assert_array_equal(mixed.success[::2], alone.success[::2])
    np.testing.assert_allclose(mixed.time_s[::2], alone.time_s[::2])
    np.testing.assert_allclose(mixed.final_tip_pos[::2], alone.final_tip_pos[::2], atol=1e-9)


def test_results_do_not_depend_on_threads_or_slots():
    specs = _specs("circle", 6, seed=3, linear_error=0.002, angular_error=np.deg2rad(3.0))
    config = TrialConfig(time_limit_s=3.0)
    a = run_trials(specs, baseline_params(), "mujoco", config, threads=1, slots_per_thread=6)
    b = run_trials(specs, baseline_params(), "mujoco", config, threads=2, slots_per_thread=1)
    np.testing.assert_array_equal(a.success, b.success)
    np.testing.assert_allclose(a.final_tip_pos, b.final_tip_pos, atol=1e-9)


def test_protective_stop_and_contact_metrics():
    """A lower tool-force limit stops exactly the trials whose sensed force passed it (a failure,
    flagged); the others run as before. Peak force and chatter are recorded for every trial."""
    specs = _specs("square", 6, seed=8, linear_error=0.003, angular_error=np.deg2rad(4.0))
    config = TrialConfig(time_limit_s=3.0)
    normal = run_trials(specs, baseline_params(), engine="mujoco", config=config)
    assert np.all(np.isfinite(normal.chatter)) and np.all(normal.chatter >= 0)
    assert np.all(normal.peak_force > 0) and not normal.protective_stop.any()
    limit = float(np.median(normal.peak_force))
    stopped = run_trials(
        specs, baseline_params(), engine="mujoco", config=config.replace(max_tool_force=limit)
    )
    passed = normal.peak_force > limit
    assert passed.any() and not passed.all()
    np.testing.assert_array_equal(stopped.protective_stop, passed)
    assert not stopped.success[passed].any() and np.all(stopped.reward[passed] < 38000.0)
    assert np.all(stopped.steps[passed] < normal.steps[passed])
    for name in ("success", "steps", "chatter", "peak_force"):
        np.testing.assert_array_equal(
            getattr(stopped, name)[~passed], getattr(normal, name)[~passed], err_msg=name
        )


def test_chatter_metric_sees_the_old_oscillation_and_not_the_damped_loop():
    """The coupling without sensor, damping or gentle approach (the engines before issue 18)
    alternates the axial force by ~100 N per step on a peg stuck on the rim; the default trial
    does not."""
    from mjx_peg.skill import dmp, sensor

    specs = _specs("square", 6, seed=1, linear_error=0.003, angular_error=np.deg2rad(4.0))
    ideal = sensor.SensorConfig(cutoff_hz=np.inf, delay_steps=0, force_noise=0.0,
                                torque_noise=0.0, force_bias=0.0, torque_bias=0.0)  # fmt: skip
    old = TrialConfig(
        time_limit_s=3.0, sensor=ideal, coupling_time_constant=0.0, max_tool_force=1e9,
        dmp=dmp.DMPConfig(n_basis=20, alpha_s=4.0, duration=1.0),
    )  # fmt: skip
    from mjx_peg.skill.params import ControllerParams, vector_from_controller

    first = np.diag([1e-3, 1e-3, 1e-3, 0.05, 0.05, 0.01])  # the first hand-tuned baseline
    first[1, 3], first[0, 4] = 3e-3, -3e-3
    first = vector_from_controller(ControllerParams(np.asarray(300.0), np.asarray(300.0), first))
    before = run_trials(specs, first, engine="mujoco", config=old)
    now = run_trials(specs, first, engine="mujoco", config=TrialConfig(time_limit_s=4))
    print("before:", before.contact_summary(), "| now:", now.contact_summary())
    assert np.median(before.chatter[before.time_s > 1.2]) > 50.0
    assert np.median(now.chatter[now.time_s > 1.2]) < 1.0
    assert np.median(now.peak_force) < 0.6 * np.median(before.peak_force)


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
    At larger errors contact-heavy trials part between the engines; the 100-spec comparison is
    in the closing note of the engines issue. The F/T pipeline itself is the same function on
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


def _mixed_specs(n, seed):
    """Every shape at two sizes, errors large enough that some trials fail."""
    config = TaskConfig(
        shapes=("circle", "square", "triangle"),
        sizes=(0.05, 0.06),
        linear_error=0.004,
        angular_error=np.deg2rad(6.0),
    )
    return sample_trials(config, seed, n)


def test_results_do_not_depend_on_lanes_slots_or_batch_threads():
    """One lane or two, few slots or many, 1 or 2 C threads per batch: bit-identical results,
    progress for every trial (slots recycled across scenes), the batches reused across calls."""
    from mjx_peg.engines import sims

    specs = _mixed_specs(12, seed=6)
    params = np.tile(baseline_params(), (12, 1))
    params[5, :2] = 1e9  # one trial blows up
    config = TrialConfig(time_limit_s=3.0)  # the approach takes 2 s
    local = run_trials(specs, params, engine="mujoco", config=config, threads=1)
    counts = []
    lanes = run_trials(
        specs, params, engine="mujoco", config=config, threads=2, slots_per_thread=3,
        progress=counts.append,
    )  # fmt: skip
    assert sum(counts) == 12
    assert local.unstable[5] and 0 < local.success.sum() < 12, local.summary()
    local = run_trials(specs, params, engine="mujoco", config=config, threads=1)
    cached = {id(s) for s in sims.pooled()}
    again = run_trials(specs, params, engine="mujoco", config=config, threads=1)
    assert {id(s) for s in sims.pooled()} == cached
    threaded = run_trials(specs, params, engine="mujoco", config=config, threads=1, batch_threads=2)
    one_data = run_trials(specs, params, engine="mujoco", config=config, persistent=False)
    data_each = run_trials(specs, params, engine="mujoco", config=config, persistent=True)
    for other in (lanes, again, threaded, one_data, data_each):
        for name, value in local.to_arrays().items():
            np.testing.assert_array_equal(getattr(other, name), value, err_msg=name)


@pytest.mark.parametrize("persistent", [True, False])
def test_batch_step_is_mj_step2_then_mj_step1(persistent):
    """The engine's physics: Batch.step(stage=mjSTAGE_VEL) from forward(ACC), forward(VEL) is
    C MuJoCo's start_trial, mj_step1, then (ctrl, mj_step2, mj_step1) per step, to the bit."""
    import mujoco

    from mjx_peg.engines.sims import Sims
    from mjx_peg.world import scene

    specs, n = _mixed_specs(40, seed=9), 4
    specs = specs.take(np.flatnonzero(specs.shape_id == 1)[:n])  # squares
    sims = Sims(("square", float(specs.size[0])), n, nthread=2, persistent=persistent)
    models = [scene.load_model("square", float(specs.size[0])) for _ in range(n)]
    datas = [mujoco.MjData(m) for m in models]
    for i in range(n):
        sims.load(i, specs, i)
        scene.start_trial(specs, i, models[i], datas[i], sims.ids)
        mujoco.mj_step1(models[i], datas[i])
    ids = np.arange(n, dtype=np.int32)
    sims.forward(ids)
    rng = np.random.default_rng(0)
    for _ in range(200):
        torques = rng.normal(size=(n, 6)) * 5.0 + np.array([d.qfrc_bias for d in datas])
        for m, d, u in zip(models, datas, torques, strict=True):
            d.ctrl[:] = u
            mujoco.mj_step2(m, d)
            mujoco.mj_step1(m, d)
        sims.step(ids, torques)
        for i, d in enumerate(datas):
            for field in ("qpos", "qvel", "site_xpos", "site_xmat", "sensordata", "qfrc_bias"):
                got = sims.batch.bind(field)[i]
                np.testing.assert_array_equal(got, getattr(d, field), err_msg=field)
            assert sims.time[i] == d.time


def test_jacobians_and_mass_match_mujoco():
    """`jacobians` is mj_jacSite and mj_jacDot, the dense mass matrix mj_fullM, to the bit."""
    import mujoco

    from mjx_peg.engines.jacobian import dense_mass_index, jacobians
    from mjx_peg.world import scene

    m = scene.load_model("circle", 0.05)
    ids = scene.scene_ids(m)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    index = dense_mass_index(m)
    for _ in range(20):
        d.qpos[:] = rng.uniform(-np.pi, np.pi, 6)
        d.qvel[:] = rng.normal(size=6)
        mujoco.mj_step1(m, d)
        jl, ja, dl, da = (np.zeros((3, 6)) for _ in range(4))
        mujoco.mj_jacSite(m, d, jl, ja, ids.tcp_site)
        mujoco.mj_jacDot(m, d, dl, da, d.site_xpos[ids.tcp_site], ids.wrist3_body)
        root = m.body_rootid[ids.wrist3_body]
        jac, jac_dot = jacobians(
            d.cdof[None], d.cdof_dot[None], d.cvel[ids.wrist3_body][None],
            d.subtree_com[root][None], d.site_xpos[ids.tcp_site][None],
        )  # fmt: skip
        np.testing.assert_array_equal(jac[0], np.concatenate([jl, ja]))
        np.testing.assert_array_equal(jac_dot[0], np.concatenate([dl, da]))
        mass = np.zeros((6, 6))
        mujoco.mj_fullM(m, d, mass)
        np.testing.assert_array_equal(d.M[index].reshape(6, 6), mass)


def test_an_error_in_a_lane_is_one_clear_error(monkeypatch):
    """A lane that fails stops the call with its exception in the caller; the next call runs."""
    from mjx_peg.engines import period

    specs = _mixed_specs(8, seed=7)
    config = TrialConfig(time_limit_s=0.5)
    calls, original = [0], period.skill_torque

    def failing(*args):
        calls[0] += 1
        if calls[0] == 30:
            raise RuntimeError("controller failed")
        return original(*args)

    monkeypatch.setattr(period, "skill_torque", failing)
    with pytest.raises(RuntimeError, match="controller failed"):
        run_trials(specs, baseline_params(), engine="mujoco", config=config, threads=2)
    monkeypatch.setattr(period, "skill_torque", original)
    result = run_trials(specs, baseline_params(), engine="mujoco", config=config, threads=2)
    assert len(result) == 8 and result.steps.min() > 0


def test_engine_never_imports_jax():
    """The CPU engine imports only NumPy, MuJoCo and the trial definition."""
    import subprocess
    import sys

    code = (
        "import sys; import mjx_peg.engines.mujoco, mjx_peg.engines.lanes; "
        "sys.exit(any(m == 'jax' or m.startswith('jax.') for m in sys.modules))"
    )
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0
    with pytest.raises(ValueError, match="observer"):
        run_trials(_specs("square", 2, seed=8), baseline_params(), engine="mujoco",
                   observer=lambda *a: None, threads=2)  # fmt: skip


_LONG_CALL = (
    "import numpy as np\n"
    "from mjx_peg.skill.baseline import baseline_params\n"
    "from mjx_peg.engines import run_trials\n"
    "from mjx_peg.world.task import TaskConfig, sample_trials\n"
    "from mjx_peg.engines.trial import TrialConfig\n"
    "specs = sample_trials(TaskConfig(shapes=('square',)), 1, 40)\n"
    "def started(count):\n"
    "    print('started', flush=True)\n"
    "params = np.tile(baseline_params(), (40, 1))\n"
    "params[1:, 0] = 1e-6  # almost no stiffness: the rest hover to the time limit\n"
    "params[0, :2] = 1e9  # ends at once, so progress reports while the rest run\n"
    "run_trials(specs, params, engine='mujoco', threads=2, progress=started,\n"
    "           config=TrialConfig(time_limit_s=600.0))\n"
)


@pytest.mark.serial  # timed: run alone (README's test command)
@pytest.mark.parametrize("lanes", ["threads", "processes"])
def test_interrupting_the_caller_stops_the_call(lanes):
    """Ctrl-C mid-call: KeyboardInterrupt in the caller within a second or two, the lanes
    stopped. Lanes as threads start no process; lanes in worker processes (processes=2) stop
    with the caller: killed on Ctrl-C, and dying with it on SIGKILL."""
    import signal
    import subprocess
    import sys

    code = _LONG_CALL.replace("threads=2,", f"{lanes}=2,")
    for sig in (signal.SIGINT, signal.SIGKILL):
        caller = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)  # fmt: skip
        assert caller.stdout.readline().strip() == "started"
        workers = _children(caller.pid)
        assert len(workers) >= 2 if lanes == "processes" else workers == []
        start = time.monotonic()
        caller.send_signal(sig)
        _, err = caller.communicate(timeout=10.0)
        assert time.monotonic() - start < 2.0
        if sig == signal.SIGINT:
            assert "KeyboardInterrupt" in err and caller.returncode != 0
        deadline = time.monotonic() + 5.0
        while any(map(_running, workers)) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not [w for w in workers if _running(w)]


def _children(pid: int) -> list[int]:
    """Processes whose parent is `pid`."""
    import pathlib

    tasks = pathlib.Path(f"/proc/{pid}/task")
    return [int(c) for t in tasks.iterdir() for c in (t / "children").read_text().split()]


def test_settle_update_ends_rest_and_repeating_oscillations_only():
    """At rest or repeating the same oscillation after settle_after_s: settled one window after
    the first window that matches its predecessor; drifting or before settle_after_s: never."""
    from mjx_peg.engines.trial import is_settled, settle_start, settle_update

    config = TrialConfig(settle_after_s=1.0, settle_window_s=0.5)
    dt = config.timestep
    steps = np.arange(int(6.0 / dt))
    t = steps * dt
    chatter = np.where(steps % 2 == 0, 50.0, -50.0)  # a 250 Hz force oscillation
    cases = {
        "rest": (np.zeros_like(t), np.zeros_like(t), 2.0),
        "chatter": (np.zeros_like(t), chatter, 2.0),
        # settles only once it stops moving at 3 s: windows [3, 3.5) and [3.5, 4) match
        "stops at 3 s": (1e-3 * np.minimum(t, 3.0), np.zeros_like(t), 4.0),
        "creeps": (2e-4 * t, np.zeros_like(t), None),  # 0.2 mm/s: 0.1 mm per window
        "chatter grows": (np.zeros_like(t), chatter * (1 + t), None),
    }
    for name, (tip_z, force, expected) in cases.items():
        state, settled_at = settle_start(), None
        for k in steps:
            tip = np.array([0.4, 0.1, 0.08 + tip_z[k]])
            wrench = np.array([0.0, 0.0, force[k], 0.0, 0.0, 0.0])
            state = settle_update(state, k, np.zeros(6), tip, wrench, config)
            if settled_at is None and is_settled(state, config):
                settled_at = (k + 1) * dt
        if expected is None:
            assert settled_at is None, name
        else:
            assert settled_at == pytest.approx(expected), name
    assert not is_settled(state._replace(matched=5), config.replace(end_settled=False))


def test_settled_trials_end_early_with_the_outcome_of_the_full_run():
    """Failures at rest end early (flagged settled); every trial has the outcome of the paper's
    protocol (end_settled=False), the others the same result to the bit.

    Under the credible trial a failure on the board top comes to rest late: the sensor's bias
    through the compliance leaves a lateral press under which the peg creeps (0.2-0.7 mm/s,
    decelerating over 10-20 s, MuJoCo's soft friction; 168 of 209 failures of the 500-trial
    benchmark settled within 60 s), and a creeping trial may still slide in (it must not end).
    Trials at rest here: the skill with almost no translational stiffness hovers where it starts,
    its wrench (noise and bias, filtered and damped) steady; beside them, trials that insert."""
    specs = _specs("circle", 6, seed=3, linear_error=0.0005, angular_error=np.deg2rad(0.5))
    params = np.tile(baseline_params(), (6, 1))
    params[::2, 0] = 1e-6  # k_t: hovers at rest from the start
    config = TrialConfig(time_limit_s=8.0)
    early = run_trials(specs, params, engine="mujoco", config=config)
    full = run_trials(specs, params, engine="mujoco",
                      config=config.replace(end_settled=False))  # fmt: skip
    print(early.summary(), early.steps)
    assert early.settled.sum() >= 2 and not full.settled.any()
    np.testing.assert_array_equal(early.success, full.success)
    assert early.success.any() and not (early.settled & early.success).any()
    assert np.all(early.steps[early.settled] < full.steps[early.settled])
    for name, value in full.to_arrays().items():
        if name != "settled":
            np.testing.assert_array_equal(getattr(early, name)[~early.settled],
                                          value[~early.settled], err_msg=name)  # fmt: skip


def test_start_trial_edits_only_the_fields_the_engine_expands():
    """The batch gives each simulation its own TRIAL_MODEL_FIELDS; scene.start_trial must edit
    no other model field."""
    import mujoco

    from mjx_peg.engines import sims
    from mjx_peg.world import scene

    specs = _mixed_specs(6, seed=10)
    for i in range(len(specs)):
        key = sims.scene_key(specs, i)
        before, m = scene.load_model(*key), scene.load_model(*key)
        scene.start_trial(specs, i, m, mujoco.MjData(m), scene.scene_ids(m))
        changed = {
            name for name in dir(m)
            if isinstance(getattr(m, name, None), np.ndarray)
            and not np.array_equal(getattr(m, name), getattr(before, name))
        }  # fmt: skip
        assert changed <= set(sims.TRIAL_MODEL_FIELDS), changed


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


def _running(pid: int) -> bool:
    """The process exists and is not a zombie (killed, waiting to be reaped)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False
