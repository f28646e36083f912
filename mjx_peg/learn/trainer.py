"""`train(config, out)`: run (or resume) a training job in a run directory and export it.

The host loop around `ppo.make_iteration`: restore the last Orbax checkpoint if the run was
interrupted, step iterations with a progress bar (trials/s, ETA), append metrics.csv and
trials.csv, checkpoint every `checkpoint_every_s` seconds and at the end, then export
`policy.npz` + `manifest.json` and draw `training_curve.png`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import jax
import jax.experimental.multihost_utils
import jax.numpy as jnp
import numpy as np

from mjx_peg import outdir, signals
from mjx_peg.engines import interrupt
from mjx_peg.errors import UsageError
from mjx_peg.learn import checkpoints, ppo
from mjx_peg.learn.checkpoints import Checkpoints
from mjx_peg.learn.config import TrainConfig
from mjx_peg.learn.curves import plot_training_curve, running_mean
from mjx_peg.learn.env import InsertionEnv
from mjx_peg.learn.monitor import Board, HeldOut
from mjx_peg.learn.run_dir import RunDir
from mjx_peg.policy.export import PolicyError, load_policy, save_policy
from mjx_peg.policy.observation import PRIVILEGED_NAMES
from mjx_peg.skill.params import N_LEARNED, N_PARAMS


@dataclass(frozen=True)
class TrainSummary:
    run_dir: Path
    trials: int
    iterations: int
    wall_s: float
    final_mean_return: float  # running mean over the last 100 trials (paper scale)
    final_success_rate: float  # over the last iteration's trials
    finished: bool

    def line(self) -> str:
        state = "finished" if self.finished else "stopped"
        return (
            f"{state}: {self.trials} trials in {self.iterations} iterations, "
            f"{self.wall_s / 60:.1f} min; mean return of the last 100 trials "
            f"{self.final_mean_return:.0f} / 38000, last-iteration success "
            f"{100 * self.final_success_rate:.1f} %; {self.run_dir}"
        )


def _save(saved: Checkpoints, state: ppo.TrainingState) -> None:
    saved.save(int(state.iteration), state)


def load_init(config: TrainConfig, template: ppo.TrainingState) -> ppo.TrainingState:
    """Start from another run's networks and observation statistics (fresh optimizer): its last
    Orbax checkpoint, or, where it has none (a shipped policy under policies/), its exported
    policy (`_from_export`)."""
    source = RunDir(config.init_from)
    if not source.path.is_dir():
        raise UsageError(f"--init-from {source.path} is not a directory")
    other = source.read_config()
    has_checkpoint = checkpoints.has_steps(source.checkpoint_dir)  # else its critic is not used
    # a run of another action size starts from its export (`_from_export` widens 38 to 47)
    has_checkpoint = has_checkpoint and other.action_size == config.action_size
    critic_differs = has_checkpoint and other.value_hidden != config.value_hidden
    if other.observation != config.observation:
        raise UsageError(
            f"--init-from {source.path} observes the {other.observation} layout, this run the "
            f"{config.observation} one"
        )
    if other.policy_hidden != config.policy_hidden or critic_differs:
        raise UsageError(
            f"--init-from {source.path} has networks {other.policy_hidden}/{other.value_hidden}, "
            f"this run {config.policy_hidden}/{config.value_hidden}"
        )
    if not has_checkpoint:
        return _from_export(config, template, source)
    with source.checkpoints() as saved:
        restored = saved.restore(ppo.init_state(other, ppo.make_networks(other)))
    return template.replace(
        params=restored.params,
        normalizer_params=restored.normalizer_params,
        optimizer_state=ppo.make_optimizer(config).init(restored.params),
    )


def _from_export(config: TrainConfig, template: ppo.TrainingState, source: RunDir):
    """`template` with an exported policy's mean path and observation statistics.

    policy.npz keeps what acting needs: the mean path's layers and the policy input's mean and
    std. The rest starts as a fresh run's does: the exploration std (`config`'s), the critic, and
    the statistics of the critic's eight privileged features (mean 0, std 1: they are scaled to
    O(1) by construction, observation.privileged). The statistics count the source's trials, as
    its checkpoint's would, so this run's trials move them as they would have moved those."""
    try:
        policy = load_policy(source.path)
    except PolicyError as e:
        raise UsageError(f"--init-from {source.path} holds no checkpoint, and {e}") from None
    *hidden, head = [{"kernel": jnp.asarray(k), "bias": jnp.asarray(b)} for k, b in policy.layers]
    width = head["bias"].shape[0]
    if width < config.action_size:  # a policy of the 38 alone: its search starts at the prior
        extra = config.action_size - width
        head = {
            "kernel": jnp.concatenate([head["kernel"], jnp.zeros((len(head["kernel"]), extra))], 1),
            "bias": jnp.concatenate([head["bias"], jnp.asarray(ppo.prior_action(config)[width:])]),
        }
    elif width == N_LEARNED and config.action_size == N_PARAMS:
        # the 38 of a policy that also learned the skill's constants: this run holds those at
        # the skill's values, so its controller starts from the source's and the rest is dropped
        head = {"kernel": head["kernel"][:, :N_PARAMS], "bias": head["bias"][:N_PARAMS]}
    elif width > config.action_size:
        raise UsageError(
            f"--init-from {source.path} outputs {width} numbers, this run learns "
            f"{config.action_size}: train with the search's constants learned"
        )
    # the export outputs the map's action; this run's network acts in its own units
    head = {k: ppo.from_map_action(config, np.asarray(v)) for k, v in head.items()}
    tree = {
        **template.params.policy["params"],
        "MLP_0": {f"hidden_{i}": layer for i, layer in enumerate(hidden)},
        "Dense_0": head,
    }
    params = template.params.replace(policy={"params": tree})
    extra = len(PRIVILEGED_NAMES)
    mean = {
        "state": policy.obs_mean,
        "privileged_state": np.concatenate([policy.obs_mean, np.zeros(extra, np.float32)]),
    }
    std = {
        "state": policy.obs_std,
        "privileged_state": np.concatenate([policy.obs_std, np.ones(extra, np.float32)]),
    }
    count = int(policy.manifest["trials"])
    norm = template.normalizer_params
    norm = norm.replace(
        count=type(norm.count)(hi=jnp.uint32(count >> 32), lo=jnp.uint32(count & 0xFFFFFFFF)),
        mean={k: jnp.asarray(v, jnp.float32) for k, v in mean.items()},
        std={k: jnp.asarray(v, jnp.float32) for k, v in std.items()},
        summed_variance={k: jnp.asarray(v**2 * count, jnp.float32) for k, v in std.items()},
    )
    return template.replace(
        params=params,
        normalizer_params=norm,
        optimizer_state=ppo.make_optimizer(config).init(params),
    )


# training_curve.png is redrawn at most this often while a run trains, and when it finishes (an
# interrupted run's, when it resumes): a redraw costs ~0.45 s (matplotlib), a third of a tiny
# run's iteration here
CURVE_EVERY_S = 30.0


def _draw_curve(run: RunDir, config: TrainConfig) -> None:
    """Redraw training_curve.png from the run's tables (a curve to watch while it trains)."""
    title = f"{config.preset}: {run.path.name}"
    outdir.write_atomic(
        run.curve_path,
        lambda p: plot_training_curve(run.trials_path, p, title, run.metrics_path, run.eval_path),
    )


def _export(run: RunDir, config: TrainConfig, state: ppo.TrainingState, finished: bool):
    """policy.npz and manifest.json of `state` in `run`'s folder."""
    norm = state.normalizer_params
    save_policy(
        run.path,
        ppo.policy_layers(config, state.params),
        np.asarray(norm.mean["state"]),
        np.asarray(norm.std["state"]),
        config.to_json(),
        centre=config.map_centre(),
        part_range=config.part_range(),
        extra={
            "finished": finished,
            "trials": int(state.trials),
            "wall_s": float(state.wall_s),
            "trainer": "brax PPO (mjx_peg/learn/ppo.py)",
        },
    )


def train(
    config: TrainConfig,
    out,
    force: bool = False,
    checkpoint_every_s: float = 60.0,
    progress: bool = True,
    engine_options: dict | None = None,
    note: Callable[[str], None] | None = None,
    tensorboard: bool = False,
) -> TrainSummary:
    """Train (or resume) into `out`. `tensorboard` writes every metric to RUN_DIR/tensorboard
    as well (`monitor.Board`).

    Everything is checked before `out` is touched: what `out` holds (RunDir.plan), that it is
    not --init-from's run, and the --init-from checkpoint itself. With `force` an earlier run in
    `out` is moved aside (`note` is told where), never deleted, and nothing but a run is."""
    devices = jax.device_count()
    if config.num_envs % (devices * config.num_minibatches):
        raise UsageError(
            f"--num-envs {config.num_envs} must be a multiple of {devices} devices x "
            f"{config.num_minibatches} minibatches"
        )
    run = RunDir(out)
    # With jax.distributed every process runs this loop on the same (shared) run directory;
    # process 0 writes the files, all take part in Orbax's checkpoint saves.
    primary = jax.process_index() == 0
    plan = run.plan(config, force, config.init_from) if primary else "resume"
    state = ppo.init_state(config, ppo.make_networks(config))
    resuming = plan == "resume" and checkpoints.has_steps(run.checkpoint_dir)
    initial = None
    if config.init_from and not resuming:
        initial = load_init(config, state)  # read before `out` is touched
    signals.working()  # from here a Ctrl-C unwinds: every finished iteration is kept
    if primary:
        run.prepare(config, plan, note)
    if jax.process_count() > 1:
        jax.experimental.multihost_utils.sync_global_devices("run dir prepared")
    env = InsertionEnv(config.task(), config.trial(), config.engine, engine_options,
                       config.map_centre(), config.observation, config.action_size,
                       ppo.action_transform(config))  # fmt: skip
    manager = run.checkpoints()
    if primary:
        manager.drop_partial()
    if plan == "resume" and manager.latest_step() is not None:
        try:
            state = manager.restore(state)
        except BaseException:
            manager.close()
            raise
        if primary:
            run.truncate_tables(int(state.trials))
    else:
        if config.init_from:
            state = initial if initial is not None else load_init(config, state)
        elif config.obs_statistics == "context":
            state = state.replace(
                normalizer_params=ppo.context_statistics(config, state.normalizer_params)
            )
        if primary:
            run.start_tables()
    step = ppo.make_iteration(env, config)
    replicated = ppo.replicate(state)
    wall0 = float(state.wall_s)
    start = time.monotonic()
    last_save = last_curve = start
    total = config.iterations * config.num_envs
    bar = None
    if progress and primary:
        from tqdm import tqdm

        bar = tqdm(total=total, initial=int(state.trials), unit="trial", dynamic_ncols=True)
    last = {"success": np.zeros(1), "return": np.zeros(1)}
    recent = np.zeros(0)  # the returns of the last 100 trials, those of a resumed run's first
    if int(state.trials) and run.trials_path.is_file():
        from mjx_peg.learn.curves import read_table

        recent = np.asarray(read_table(run.trials_path)["return"][-100:], dtype=np.float64)
    saved, recorded = int(state.iteration), state
    held_out = HeldOut(config, engine_options) if config.eval_every and primary else None
    board = Board(run.tensorboard_dir, tensorboard and primary, int(state.trials))
    try:
        while int(state.iteration) < config.iterations:
            t0 = time.monotonic()
            with interrupt.on_stop_signals():  # Ctrl-C or SIGTERM: its trials stop at once
                try:
                    replicated, trials, metrics = step(replicated)
                except Exception:  # the host callback's KeyboardInterrupt, as JAX raises it
                    if interrupt.requested():
                        interrupt.stop()
                    raise
            # [local devices, all devices, trials per device]: every local copy is the same
            trials = {k: v.reshape(-1) for k, v in ppo.unreplicate(trials).items()}
            metrics = ppo.unreplicate(metrics)
            state = ppo.unreplicate(replicated)
            now = time.monotonic()
            wall = wall0 + now - start
            state = state.replace(wall_s=np.asarray(wall, np.float32))
            # The next iteration starts from host arrays again, as the first did: fed its own
            # outputs (other weak types), the pmapped step would compile a second time (~6 s
            # here, during which Ctrl-C cannot act).
            replicated = ppo.replicate(state)
            n = int(state.trials)
            first = n - config.num_envs
            succ = trials["success"] > 0.5
            times = trials["time_s"][succ]
            # metrics.csv's columns after iteration and trials (run_dir.METRICS_COLUMNS), wall_s
            # aside: TensorBoard's training/... scalars
            values = {
                "mean_return": trials["return"].mean(),
                "success_rate": succ.mean(),
                "time_to_complete_s": times.mean() if times.size else np.nan,
                "unstable_rate": (trials["unstable"] > 0.5).mean(),
                "settled_rate": (trials["settled"] > 0.5).mean(),
                "protective_stop_rate": (trials["protective_stop"] > 0.5).mean(),
                "peak_force_median_n": np.median(trials["peak_force"]),
                "chatter_median_n": np.median(trials["chatter"]),
                "trials_per_s": config.num_envs / (now - t0),
                "policy_loss": metrics["policy_loss"],
                "value_loss": metrics["v_loss"],
                "entropy_loss": metrics["entropy_loss"],
                "kl": metrics["kl_mean"],
                "policy_std": metrics["policy_dist_mean_std"],
                "learning_rate": metrics["learning_rate"],
            }
            values = {k: float(v) for k, v in values.items()}
            formats = (".2f", ".4f", ".4f", ".4f", ".4f", ".4f", ".2f", ".3f", ".2f") + (".5g",) * 6
            cells = [format(v, f) if np.isfinite(v) else "" for v, f in
                     zip(values.values(), formats, strict=True)]  # fmt: skip
            row = (
                [int(state.iteration), n] + cells[:8] + [f"{wall:.2f}"] + cells[8:],
                [
                    [first + i, f"{r:.2f}", int(s), f"{t:.4f}" if s else ""]
                    for i, (r, s, t) in enumerate(
                        zip(trials["return"], succ, trials["time_s"], strict=True)
                    )
                ],
            )
            finished = int(state.iteration) >= config.iterations
            if primary:
                run.append(*row)
                board.scalars("training", values, n)
                due = config.eval_every and int(state.iteration) % config.eval_every == 0
                if held_out is not None and (due or finished):
                    held = held_out.evaluate(state)
                    run.append_eval([int(state.iteration), n] + [f"{v:.4f}" for v in held.values()])
                    board.scalars("eval", held, n)
                if finished or now - last_curve >= CURVE_EVERY_S:
                    _draw_curve(run, config)
                    last_curve = time.monotonic()
            recorded = state  # its trials are in trials.csv: what an interrupt keeps
            last = trials
            recent = np.concatenate([recent, trials["return"]])[-100:]
            if finished or now - last_save >= checkpoint_every_s:
                _save(manager, state)
                saved, last_save = int(state.iteration), time.monotonic()
            if bar is not None:
                bar.update(config.num_envs)
                bar.set_postfix_str(
                    f"success {100 * succ.mean():.0f}%, return {trials['return'].mean():.0f}"
                )
    except KeyboardInterrupt:  # keep every finished iteration: only the trials in flight are lost
        if primary and int(recorded.iteration) > saved:
            _save(manager, recorded)
        raise
    finally:
        if bar is not None:
            bar.close()
        manager.close()
        board.close()
    finished = int(state.iteration) >= config.iterations
    if finished and primary:
        _export(run, config, state, finished=True)
    return TrainSummary(
        run_dir=run.path,
        trials=int(state.trials),
        iterations=int(state.iteration),
        wall_s=float(state.wall_s),
        final_mean_return=float(running_mean(recent, 100)[-1]) if recent.size else math.nan,
        final_success_rate=float(np.mean(last["success"])),
        finished=finished,
    )


def export_checkpoint(run_dir, iteration: int, out) -> int:
    """The policy of `run_dir`'s checkpoint after `iteration` exported to the folder `out` as the
    trainer exports a run (config.json, policy.npz, manifest.json; marked unfinished), so that
    evaluation and the arm run it; returns the trials it had trained on. A run keeps its last
    few checkpoints: UsageError names those it keeps. `out` must be new or empty."""
    run, target = RunDir(run_dir), RunDir(out)
    if target.path.exists() and (not target.path.is_dir() or any(target.path.iterdir())):
        raise UsageError(f"{target.path} exists and is not an empty folder: export to a new one")
    config = run.read_config()
    with run.checkpoints() as saved:
        kept = saved.steps()
        if iteration not in kept:
            raise UsageError(f"{run.path} keeps the checkpoints after iterations "
                             f"{', '.join(map(str, kept)) or 'none'}, not {iteration}")  # fmt: skip
        state = saved.restore(ppo.init_state(config, ppo.make_networks(config)), iteration)
    outdir.prepare_dir(target.path)
    outdir.write_atomic(target.config_path, config.dumps())
    _export(target, config, state, finished=False)
    return int(state.trials)


def load_state(run_dir) -> tuple[TrainConfig, ppo.TrainingState]:
    """The config and the latest checkpointed TrainingState of a run directory."""
    run = RunDir(run_dir)
    config = run.read_config()
    with run.checkpoints() as saved:
        if saved.latest_step() is None:
            raise UsageError(f"{run.path} holds no checkpoint")
        return config, saved.restore(ppo.init_state(config, ppo.make_networks(config)))


__all__ = ["InsertionEnv", "TrainSummary", "export_checkpoint", "load_state", "train"]
