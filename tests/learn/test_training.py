"""Training: env semantics, the exported policy, exact resume, devices, CLI errors."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from brax.envs.wrappers.training import VmapWrapper

from mjx_peg.engines import run_trials
from mjx_peg.learn.config import PRESETS, TrainConfig
from mjx_peg.learn.curves import read_table
from mjx_peg.learn.env import InsertionEnv, specs_from_seeds
from mjx_peg.learn.ppo import deterministic_actions
from mjx_peg.learn.trainer import load_state, train
from mjx_peg.policy import observation
from mjx_peg.policy.export import load_policy
from mjx_peg.policy.network import controller_vector
from mjx_peg.skill.search import SKILLS, NamedSkill

ROOT = Path(__file__).resolve().parents[2]
# A tiny run: 3 iterations of 16 trials of at most 0.6 s.
# `python train.py` with TINY_ARGS: the quick preset (its skill, the spiral, and its movement)
TINY = PRESETS["quick"].replace(trials=48, num_envs=16, time_limit_s=0.6, seed=3)
TINY_ARGS = ["--trials", "48", "--num-envs", "16", "--time-limit", "0.6", "--seed", "3"]
DETERMINISTIC = ("iteration", "trials", "mean_return", "success_rate", "policy_loss", "kl")


def _run(args, **kwargs):
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    return subprocess.run(
        [sys.executable, "train.py", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=env,
        **kwargs,
    )


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("tiny")
    summary = train(TINY, out, progress=False)
    return out, summary


def test_env_reset_and_step_are_one_trial():
    config = TrainConfig(time_limit_s=1.0)
    centre = config.map_centre()
    env = VmapWrapper(InsertionEnv(config.task(), config.trial(), action_centre=centre))
    state = jax.jit(env.reset)(jax.random.split(jax.random.PRNGKey(1), 4))
    specs = specs_from_seeds(config.task(), np.asarray(state.info["seed"]))
    np.testing.assert_allclose(state.obs["state"], observation.observe_specs(specs), atol=1e-6)
    critic = np.concatenate(
        [observation.observe_specs(specs), observation.privileged_specs(specs)], axis=1
    )
    np.testing.assert_allclose(state.obs["privileged_state"], critic, atol=1e-6)
    action = jnp.zeros((4, 38))
    after = jax.jit(env.step)(state, action)
    expected = run_trials(
        specs, np.asarray(controller_vector(np.zeros((4, 38)), centre)), "mujoco", config.trial()
    )
    np.testing.assert_array_equal(after.done, 1.0)
    np.testing.assert_allclose(after.metrics["return"], expected.reward, rtol=1e-6)
    np.testing.assert_allclose(after.reward, expected.reward / 38000.0, rtol=1e-6)
    np.testing.assert_array_equal(after.metrics["success"], expected.success)
    # the same key is the same trial
    again = jax.jit(env.reset)(jax.random.split(jax.random.PRNGKey(1), 4))
    np.testing.assert_array_equal(again.obs["state"], state.obs["state"])


def test_run_dir_holds_the_promised_files(tiny_run):
    out, summary = tiny_run
    assert summary.finished and summary.trials == 48
    for name in ("config.json", "metrics.csv", "trials.csv", "policy.npz", "manifest.json"):
        assert (out / name).is_file(), name
    assert (out / "training_curve.png").stat().st_size > 10_000
    config = json.loads((out / "config.json").read_text())
    assert TrainConfig.from_json(config) == TINY
    spiral = NamedSkill("spiral", SKILLS["spiral"])  # the run's skill, every constant recorded
    assert config["skill_constants"] == spiral.record()["constants"]
    metrics = read_table(out / "metrics.csv")
    assert metrics["trials"] == [16.0, 32.0, 48.0]
    assert metrics["settled_rate"] == [0.0, 0.0, 0.0]  # 0.6 s trials cannot settle

    assert read_table(out / "trials.csv")["trial"] == list(range(48))
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["finished"] and manifest["action"]["param_names"][:2] == ["k_t", "k_theta"]
    assert manifest["skill"] == spiral.record()  # it runs the skill it trained with
    with np.load(out / "policy.npz", allow_pickle=False) as npz:
        assert all(npz[k].dtype == np.float32 for k in npz.files)


def test_a_rerun_whose_skill_constants_changed_is_refused(tiny_run, monkeypatch, capsys):
    """The skill's constants are part of a run's config: after one constant of the preset's
    skill changed, the same command refuses in one line naming --out and the constant."""
    from mjx_peg.learn import cli

    out, _ = tiny_run
    before = (out / "config.json").read_bytes()
    changed = PRESETS["quick"].skill_constants.replace(spiral_speed=0.04)
    monkeypatch.setitem(PRESETS, "quick", PRESETS["quick"].replace(skill_constants=changed))
    assert cli.main([*TINY_ARGS, "--no-progress", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"--out {out}" in err
    assert "skill_constants.spiral_speed: 0.03 there, 0.04 now" in err
    assert (out / "config.json").read_bytes() == before


def test_full_time_limit_flag():
    from mjx_peg.learn import cli

    args = cli.parser().parse_args([*TINY_ARGS, "--full-time-limit"])
    config = cli.resolve_config(args)
    assert config.full_time_limit and not config.trial().end_settled
    assert TINY.trial().end_settled  # the default: settled failures end early


def test_numpy_policy_equals_jax_deterministic_action(tiny_run):
    out, _ = tiny_run
    config, state = load_state(out)
    obs = np.random.default_rng(0).normal(size=(1000, observation.OBS_SIZE)).astype(np.float32)
    jax_action = np.asarray(deterministic_actions(config, state, jnp.asarray(obs)))
    np_action = load_policy(out).act(obs)
    assert np.max(np.abs(np_action - jax_action)) < 1e-5


def test_prior_starts_at_the_baseline():
    config = TINY
    from mjx_peg.learn.ppo import init_state, make_networks
    from mjx_peg.skill.baseline import baseline_params

    obs = jnp.asarray(np.random.default_rng(1).normal(size=(64, 8)), jnp.float32)
    base = baseline_params()
    for cfg in (config, config.replace(action_map="sigmoid")):
        state = init_state(cfg, make_networks(cfg))
        vec = controller_vector(deterministic_actions(cfg, state, obs), cfg.map_centre())
        vec = np.asarray(vec)
        np.testing.assert_allclose(vec[:, :2], np.broadcast_to(base[:2], (64, 2)), rtol=0.3)
        assert np.all(vec[:, 2] > 1.2e-3)  # lateral compliance near the baseline's 1.8e-3 m/N


def test_init_from_a_shipped_policy_starts_at_its_actions():
    """A run without checkpoints (policies/paper) starts from its exported mean path and
    observation statistics, counted as its trials; the exploration std and the critic fresh."""
    from mjx_peg.learn import cli
    from mjx_peg.learn.ppo import init_state, make_networks
    from mjx_peg.learn.trainer import _load_init

    config = cli.resolve_config(
        cli.parser().parse_args(["--preset", "transfer", "--init-from", "paper"])
    )
    assert Path(config.init_from).resolve() == ROOT / "policies" / "paper"
    template = init_state(config, make_networks(config))
    state = _load_init(config, template)
    shipped = load_policy("paper")
    obs = np.random.default_rng(2).normal(size=(256, observation.OBS_SIZE)).astype(np.float32)
    action = np.asarray(deterministic_actions(config, state, jnp.asarray(obs)))
    assert np.max(np.abs(action - shipped.act(obs))) < 1e-5
    norm = state.normalizer_params
    assert int(norm.count.lo) == shipped.manifest["trials"] == 8192
    critic_mean = np.asarray(norm.mean["privileged_state"])
    np.testing.assert_allclose(critic_mean[:8], shipped.obs_mean, rtol=1e-6)
    np.testing.assert_array_equal(critic_mean[8:], 0.0)
    np.testing.assert_allclose(np.asarray(norm.std["privileged_state"])[8:], 1.0)
    fresh, loaded = template.params, state.params
    assert jax.tree.all(jax.tree.map(np.array_equal, fresh.value, loaded.value))
    np.testing.assert_array_equal(
        fresh.policy["params"]["std_logparam"]["log_value"],
        loaded.policy["params"]["std_logparam"]["log_value"],
    )


@pytest.mark.slow
def test_sigkill_then_rerun_equals_an_uninterrupted_run(tiny_run, tmp_path):
    reference, _ = tiny_run
    out = tmp_path / "killed"
    args = ["--out", str(out), "--checkpoint-every", "0", "--no-progress", *TINY_ARGS]
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    proc = subprocess.Popen(
        [sys.executable, "train.py", *args],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 300
    while not (out / "checkpoints" / "1").is_dir() and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not (out / "policy.npz").exists(), "the run finished before it was killed"
    done = _run(args)
    assert done.returncode == 0, done.stderr
    a, b = read_table(reference / "metrics.csv"), read_table(out / "metrics.csv")
    for column in DETERMINISTIC:
        assert a[column] == b[column], column
    assert (reference / "trials.csv").read_text() == (out / "trials.csv").read_text()
    _, s1 = load_state(reference)
    _, s2 = load_state(out)
    for x, y in zip(
        jax.tree.leaves(s1.optimizer_state), jax.tree.leaves(s2.optimizer_state), strict=True
    ):
        np.testing.assert_array_equal(x, y)
    for x, y in zip(jax.tree.leaves(s1.params), jax.tree.leaves(s2.params), strict=True):
        np.testing.assert_array_equal(x, y)


@pytest.mark.slow
def test_two_forced_host_devices(tmp_path):
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    code = (
        "import jax; from mjx_peg.learn.config import TrainConfig;"
        "from mjx_peg.learn.trainer import train;"
        "assert jax.local_device_count() == 2;"
        f"s = train(TrainConfig(trials=32, num_envs=16, time_limit_s=0.6), {str(tmp_path)!r},"
        " progress=False); print(s.trials)"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, env=env
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().endswith("32")
    returns = read_table(tmp_path / "trials.csv")["return"]
    assert len(returns) == 32
    # the two devices drew different trials
    assert returns[:8] != returns[8:16]


def test_cli_bad_input_is_one_line(tmp_path, tiny_run):
    reference, _ = tiny_run
    broken = tmp_path / "broken"
    broken.mkdir()
    for name in ("config.json", "manifest.json"):
        (broken / name).write_bytes((reference / name).read_bytes())
    (broken / "policy.npz").write_bytes((reference / "policy.npz").read_bytes()[:100])
    cases = [
        ["--preset", "nope"],
        ["--trials", "-5"],
        ["--preset", "transfer", "--init-from", str(tmp_path)],
        ["--preset", "transfer", "--init-from", str(broken)],
        ["--preset", "transfer", "--init-from", "baseline"],
        ["--out", str(reference), *TINY_ARGS],  # a finished run, no --force
    ]
    for args in cases:
        done = _run(args)
        assert done.returncode == 2, (args, done.stderr)
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("train.py: error:"), (args, done.stderr)
    assert "--force" in _run(["--out", str(reference), *TINY_ARGS]).stderr


@pytest.mark.slow
def test_distributed_two_local_processes(tmp_path):
    import socket

    with socket.socket() as s:
        s.bind(("localhost", 0))
        port = s.getsockname()[1]
    out = tmp_path / "dist"
    procs = []
    for i in range(2):
        env = {
            **os.environ,
            "JAX_PLATFORMS": "cpu",
            "JAX_COORDINATOR_ADDRESS": f"localhost:{port}",
            "JAX_NUM_PROCESSES": "2",
            "JAX_PROCESS_ID": str(i),
        }
        args = ["--distributed", "--out", str(out), "--no-progress", *TINY_ARGS[:2]]
        args += ["--num-envs", "16", "--time-limit", "0.6"]
        procs.append(
            subprocess.Popen(
                [sys.executable, "train.py", *args],
                cwd=ROOT,
                env=env,
                text=True,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
            )
        )
    outputs = [p.communicate(timeout=600) for p in procs]
    for p, (_, stderr) in zip(procs, outputs, strict=True):
        assert p.returncode == 0, stderr[-2000:]
    # both processes took part in every iteration and agree on the result
    assert outputs[0][0].splitlines()[-1] == outputs[1][0].splitlines()[-1]
    assert read_table(out / "metrics.csv")["trials"] == [16.0, 32.0, 48.0]
    assert len(read_table(out / "trials.csv")["trial"]) == 48
    assert load_policy(out).manifest["finished"]
