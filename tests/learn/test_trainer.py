"""learn/trainer.py: a run directory holds what it promises, resumes exactly after SIGKILL, starts
from another run's policy, and runs on two devices or two processes."""

import dataclasses
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_peg.learn.config import TrainConfig
from mjx_peg.learn.curves import read_table
from mjx_peg.learn.ppo import deterministic_actions
from mjx_peg.learn.trainer import load_state, train
from mjx_peg.policy import observation
from mjx_peg.policy.export import load_policy
from mjx_peg.policy.network import controller_vector
from mjx_peg.skill.search import SKILLS, NamedSkill

ROOT = Path(__file__).resolve().parents[2]

DETERMINISTIC = ("iteration", "trials", "mean_return", "success_rate", "policy_loss", "kl")


def test_run_dir_holds_the_promised_files(tiny_run, tiny_config):
    out, summary = tiny_run
    assert summary.finished and summary.trials == 48
    for name in ("config.json", "metrics.csv", "trials.csv", "policy.npz", "manifest.json"):
        assert (out / name).is_file(), name
    assert (out / "training_curve.png").stat().st_size > 10_000
    config = json.loads((out / "config.json").read_text())
    assert TrainConfig.from_json(config) == tiny_config
    spiral = NamedSkill("spiral", SKILLS["spiral"])  # the run's skill, every constant recorded
    assert config["skill_constants"] == spiral.record()["constants"]
    metrics = read_table(out / "metrics.csv")
    assert metrics["trials"] == [16.0, 32.0, 48.0]
    assert metrics["settled_rate"] == [0.0, 0.0, 0.0]  # 0.6 s trials cannot settle

    assert read_table(out / "trials.csv")["trial"] == list(range(48))
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["finished"] and manifest["action"]["param_names"][:2] == ["k_t", "k_theta"]
    assert manifest["skill"] == spiral.record()  # it runs the skill it trained with
    recorded = manifest["observation"]["part_range"]  # the parts it trained on
    np.testing.assert_array_equal([recorded["low"], recorded["high"]], tiny_config.part_range())
    assert load_policy(out).part_range is not None
    with np.load(out / "policy.npz", allow_pickle=False) as npz:
        assert all(npz[k].dtype == np.float32 for k in npz.files)


def test_a_kept_checkpoint_exports_the_policy_the_run_had_then(tiny_run, tmp_path):
    """export_checkpoint: the last checkpoint's export is the run's own policy (marked
    unfinished); an iteration the run does not keep is one line naming those it keeps."""
    import pytest

    from mjx_peg.errors import UsageError
    from mjx_peg.learn.trainer import export_checkpoint

    out, _ = tiny_run
    assert export_checkpoint(out, 3, tmp_path / "at-3") == 48
    with np.load(out / "policy.npz") as ran, np.load(tmp_path / "at-3" / "policy.npz") as got:
        assert sorted(ran.files) == sorted(got.files)
        assert all(np.array_equal(ran[k], got[k]) for k in ran.files)
    manifest = json.loads((tmp_path / "at-3" / "manifest.json").read_text())
    assert (manifest["finished"], manifest["trials"]) == (False, 48)
    with pytest.raises(UsageError, match="keeps the checkpoints after iterations 3, not 1"):
        export_checkpoint(out, 1, tmp_path / "at-1")
    assert not (tmp_path / "at-1").exists()
    with pytest.raises(UsageError, match="exists and is not an empty folder"):
        export_checkpoint(out, 3, tmp_path / "at-3")  # never over another export or a run


def test_init_from_a_shipped_policy_starts_at_its_actions(paper_38):
    """A run without checkpoints (a shipped policy of the 38 alone: the `paper` shipped until
    2026-12) starts from its exported mean path and observation statistics, counted as its
    trials, the skill's constants it did not learn at the prior; the exploration std and the
    critic fresh."""
    from mjx_peg.learn import cli
    from mjx_peg.learn.ppo import init_state, make_networks
    from mjx_peg.learn.trainer import load_init

    source = paper_38
    args = ["--preset", "transfer", "--learn-skill", "--init-from", str(source)]
    config = cli.resolve_config(cli.parser().parse_args(args))
    assert Path(config.init_from).resolve() == source
    template = init_state(config, make_networks(config))
    state = load_init(config, template)
    shipped = load_policy(source)
    assert shipped.part_range is not None  # its network carries over, not its training parts
    shipped = dataclasses.replace(shipped, part_range=None)
    obs = np.random.default_rng(2).normal(size=(256, observation.OBS_SIZE)).astype(np.float32)
    action = np.asarray(deterministic_actions(config, state, jnp.asarray(obs)))
    # the shipped policy's 38; the search's constants, which it did not learn, at the prior's
    assert action.shape == (256, 47) and shipped.act(obs).shape == (256, 38)
    assert np.max(np.abs(action[:, :38] - shipped.act(obs))) < 1e-5
    np.testing.assert_allclose(action[:, 38:], 0.0, atol=1e-6)  # the centred map's centre
    vectors = np.asarray(controller_vector(action, config.map_centre()))
    np.testing.assert_allclose(vectors[:, 38:], np.broadcast_to(config.prior_vector()[38:],
                                                                (256, 9)), rtol=1e-5)  # fmt: skip
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


def test_a_fixed_skill_run_from_a_policy_of_47_starts_at_its_38():
    """--fixed-skill from a policy that also learned the skill's constants: the run's 38
    controller numbers start at the source's, its constants are the skill's."""
    from mjx_peg.learn import cli
    from mjx_peg.learn.ppo import init_state, make_networks
    from mjx_peg.learn.trainer import load_init

    source = ROOT / "docs/design/data/learning/paper_shipped/seed-0"
    args = ["--preset", "transfer", "--fixed-skill", "--init-from", str(source)]
    config = cli.resolve_config(cli.parser().parse_args(args))
    assert config.action_size == 38
    state = load_init(config, init_state(config, make_networks(config)))
    learned = load_policy(source)
    learned = dataclasses.replace(learned, part_range=None)
    width = len(observation.LAYOUTS[config.observation])  # the source's layout
    obs = np.random.default_rng(3).normal(size=(256, width)).astype(np.float32)
    action = np.asarray(deterministic_actions(config, state, jnp.asarray(obs)))
    assert action.shape == (256, 38) and learned.act(obs).shape == (256, 47)
    assert np.max(np.abs(action - learned.act(obs)[:, :38])) < 1e-5


@pytest.mark.slow
def test_sigkill_then_rerun_equals_an_uninterrupted_run(tiny_run, tmp_path, tiny_args, train_py):
    reference, _ = tiny_run
    out = tmp_path / "killed"
    args = ["--out", str(out), "--checkpoint-every", "0", "--no-progress", *tiny_args]
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
    done = train_py(args)
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


@pytest.mark.slow
def test_distributed_two_local_processes(tmp_path, tiny_args):
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
        args = ["--distributed", "--out", str(out), "--no-progress", *tiny_args[:2]]
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
    # both processes took part in every iteration and agree on the result (each reports its
    # own wall time: "in 3 iterations, 0.2 min" on one, 0.3 on the other under load)
    last = [re.sub(r"\d+\.\d+ min", "T min", out.splitlines()[-1]) for out, _ in outputs]
    assert last[0] == last[1]
    assert read_table(out / "metrics.csv")["trials"] == [16.0, 32.0, 48.0]
    assert len(read_table(out / "trials.csv")["trial"]) == 48
    assert load_policy(out).manifest["finished"]


def test_a_run_evaluates_its_mean_on_held_out_trials_and_writes_tensorboard(
    tmp_path, tiny_config, tensorboard_scalars, monkeypatch
):
    """Each iteration's held-out mean and TensorBoard scalars; the training curve, redrawn at
    most every `CURVE_EVERY_S`, is drawn when the run finishes."""
    from mjx_peg.learn import trainer

    draws = []
    monkeypatch.setattr(trainer, "CURVE_EVERY_S", 1e9)
    real = trainer.plot_training_curve
    monkeypatch.setattr(trainer, "plot_training_curve", lambda *a: draws.append(a) or real(*a))
    config = tiny_config.replace(trials=32, eval_every=1, eval_trials=4, time_limit_s=0.3)
    train(config, tmp_path / "run", progress=False, tensorboard=True)
    assert len(draws) == 1  # of two iterations, after the last
    held = read_table(tmp_path / "run" / "eval.csv")
    assert held["iteration"] == [1.0, 2.0] and held["trials"] == [16.0, 32.0]
    assert all(0.0 <= s <= 1.0 for s in held["success_rate"])
    tags = tensorboard_scalars(tmp_path / "run" / "tensorboard")
    assert [step for step, _ in tags["training/success_rate"]] == [16, 32]
    assert [step for step, _ in tags["eval/success_rate"]] == [16, 32]
    assert tags["eval/success_rate"][-1][1] == pytest.approx(held["success_rate"][-1], abs=1e-4)


def test_normalized_actions_export_the_action_the_map_takes(tmp_path, tiny_config):
    """Under normalized_actions the network acts in units of the exploration scale; the export
    folds the scale into its head, so the NumPy policy's action is the JAX policy's scaled one,
    and a run started from that export acts as it does."""
    from mjx_peg.learn.config import prior_settings
    from mjx_peg.learn.ppo import action_transform, from_map_action, to_map_action

    config = tiny_config.replace(**prior_settings("none"), trials=16)
    m = action_transform(config)
    assert config.normalized_actions and m[2, 2] == config.init_noise_std
    if config.joint_stiffness:  # k_t and k_theta: the level plus and minus the ratio
        s_l, s_r = config.init_noise_std_level, config.init_noise_std
        np.testing.assert_allclose(m[:2, :2], [[s_l, s_l], [s_r, -s_r]])
    raw = np.random.default_rng(1).normal(size=(5, config.action_size)).astype(np.float32)
    np.testing.assert_allclose(from_map_action(config, to_map_action(config, raw)), raw, atol=1e-5)
    train(config, tmp_path / "run", progress=False)
    _, state = load_state(tmp_path / "run")
    width = len(observation.LAYOUTS[config.observation])
    policy = load_policy(tmp_path / "run")
    obs = np.random.default_rng(4).normal(size=(64, width)).astype(np.float32)
    obs = observation.clip_part(obs, *policy.part_range)  # its training parts
    jax_action = np.asarray(deterministic_actions(config, state, jnp.asarray(obs)))
    np.testing.assert_allclose(policy.act(obs), jax_action, atol=1e-5)
