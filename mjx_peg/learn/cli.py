"""`python train.py`: learn the skill's 47 numbers with Brax PPO (presets in learn/config.py).

    python train.py                                  # the quick preset, on the CPU
    python train.py --preset paper --out runs/paper  # the paper's training conditions
    python train.py --preset transfer --init-from runs/paper --out runs/transfer
    python train.py --preset transfer --init-from paper --out runs/transfer  # policies/paper
    python train.py --preset paper --out runs/paper  # after a crash or kill: resumes
    python train.py --preset paper --prior none --out runs/scratch  # from a generic start
    python train.py --preset paper --seeds 0,1,2 --out runs/paper   # runs/paper/seed-N, in turn
    python -m mjx_peg.learn.seeds runs/paper         # their curves and spread, seeds.png

Bad input exits with status 2 and one line on stderr, before --out is touched. --force moves an
earlier run aside (never deletes it) and replaces nothing but a training run; --out is never the
--init-from run.
"""

from __future__ import annotations

import argparse
import contextlib
import os
from pathlib import Path

from mjx_peg import cli, outdir, signals
from mjx_peg.errors import UsageError
from mjx_peg.skill.skill_cli import skill_constant

PROG = "train.py"


MAX_TRIALS = 10_000_000  # training budget (the longest run in the README: 98,304 trials)
MAX_NUM_ENVS = 65_536  # trials per iteration


def suite_parts(text: str) -> tuple:
    """--parts: names of the suite's parts -> TrainConfig.parts (argparse's type)."""
    from mjx_peg.world import family

    names = [name for name in text.split(",") if name]
    known = {p.name: p for p in family.SUITE}
    unknown = [name for name in names if name not in known]
    if not names or unknown:
        raise argparse.ArgumentTypeError(
            f"names of the suite's parts ({', '.join(known)}), got {text!r}"
        )
    return tuple((known[n].shape, known[n].size_mm, known[n].hole_scale) for n in names)


def parser() -> argparse.ArgumentParser:
    from mjx_peg.engines import ENGINES
    from mjx_peg.learn.config import ACTION_MAPS, PRESETS, PRIORS
    from mjx_peg.policy.observation import LAYOUTS
    from mjx_peg.skill.search import SKILL_DESCRIPTIONS
    from mjx_peg.world.constants import GRASP_MODELS

    p = cli.Parser(prog=PROG, description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--preset", default="quick", choices=sorted(PRESETS), help="default: quick")
    p.add_argument("--out", type=cli.nonempty_path, help="run directory (default: runs/PRESET)")
    p.add_argument("--engine", choices=ENGINES, help="physics engine (preset: mujoco)")
    p.add_argument("--seed", type=cli.SEED, help="preset: 0")
    p.add_argument(
        "--seeds",
        type=cli.SEED_LIST,
        help="a set of runs, one per seed (e.g. 0,1,2), one after another into OUT/seed-N; "
        "a rerun resumes the set; python -m mjx_peg.learn.seeds OUT draws their spread",
    )
    p.add_argument(
        "--prior",
        choices=PRIORS,
        help="where the policy starts: baseline (preset: the hand-tuned skill) or none (Brax's "
        "initialization: every number mid-range, learned from there)",
    )
    skill = p.add_mutually_exclusive_group()
    skill.add_argument(
        "--fixed-skill",
        action="store_true",
        help="learn the 38 controller numbers alone, the skill's constants as the skill sets "
        "them (the family and transfer presets' default; the others learn them beside the 38); "
        "from an --init-from policy of 47 numbers, its 38 start the run",
    )
    skill.add_argument(
        "--learn-skill",
        action="store_true",
        help="learn the skill's constants beside the 38 controller numbers (every preset's "
        "default but family's and transfer's)",
    )
    p.add_argument(
        "--eval-every",
        type=cli.integer(0, 1_000_000),
        help="every N iterations run the policy's mean on held-out trials (eval.csv, eval/...)",
    )
    p.add_argument(
        "--tensorboard",
        action="store_true",
        help="also write every metric to OUT/tensorboard (tensorboard --logdir OUT)",
    )
    p.add_argument(
        "--kl-target",
        type=cli.number(0, 1, "", lo_open=True),
        help="the update's KL the learning rate is adapted to (preset: 0.01)",
    )
    p.add_argument(
        "--std-decay",
        type=cli.number(0, 1, "", lo_open=True),
        help="the exploration std's cap at the end of the budget, a fraction of its start, "
        "decaying geometrically (preset: 1, no cap)",
    )
    p.add_argument(
        "--parts",
        type=suite_parts,
        help="train on these parts of the suite (world/family.py, comma-separated, e.g. "
        "triangle-60-tight), linear errors x S / 50 mm; default: the preset's (the family "
        "preset: every trained part)",
    )
    p.add_argument("--num-envs", type=cli.integer(1, MAX_NUM_ENVS), help="trials per iteration")
    p.add_argument(
        "--trials",
        type=cli.integer(1, MAX_TRIALS),
        help="training budget in trials, rounded up to whole iterations of --num-envs",
    )
    p.add_argument("--time-limit", type=cli.TIME_LIMIT_S, help="per training trial")
    p.add_argument(
        "--linear-mm",
        type=cli.LINEAR_MM,
        help="+- localization x, y and grasp height error of the training trials (x S / 50 mm "
        "for the family's parts); preset: the paper's 8",
    )
    p.add_argument(
        "--angular-deg",
        type=cli.ANGULAR_DEG,
        help="+- localization yaw and grasp tilt error of the training trials; preset: the "
        "paper's 12",
    )
    p.add_argument(
        "--init-from",
        type=cli.nonempty_path,
        help="the run (or shipped policy, e.g. paper) whose networks start this run: its last "
        "checkpoint, or an exported policy's mean path with a fresh critic",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="start over in --out although it holds a run (finished, or with another config): "
        "the earlier run is moved aside to OUT.replaced-DATE-TIME (nothing but a training run is "
        "ever replaced)",
    )
    p.add_argument(
        "--checkpoint-every", type=cli.number(0, 86400, "s"), default=60.0, help="default 60"
    )
    p.add_argument(
        "--full-time-limit",
        action="store_true",
        help="run every failed trial to the time limit (default: a failure that has settled, "
        "at rest or repeating the same motion, ends early with the same outcome)",
    )
    p.add_argument(
        "--threads",
        type=cli.THREADS,
        help="CPU engine threads: per worker process (default 1), or of this process with "
        "--processes 0 (default: all cores)",
    )
    cli.add_processes_option(p, "--threads")
    cli.add_ray_option(p)
    p.add_argument(
        "--action-map",
        choices=ACTION_MAPS,
        help="how the policy's action becomes its numbers (default centred: action 0 is the "
        "baseline; sigmoid: the map of the first runs; --init-from takes its run's map)",
    )
    p.add_argument(
        "--observation",
        choices=tuple(LAYOUTS),
        help="what the policy reads of a part (default geometry: symmetry order, radii, "
        "clearance, depth; names: a one-hot of the paper's three shapes and the size, the "
        "shipped policies'; --init-from takes its run's)",
    )
    cli.add_grasp_model_option(p, GRASP_MODELS, None)  # None: the preset's
    cli.add_skill_option(p, SKILL_DESCRIPTIONS, None, "the preset's (spiral)")
    cli.add_skill_constant_option(p, skill_constant)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument(
        "--distributed",
        action="store_true",
        help="join a multi-host run through jax.distributed (JAX_COORDINATOR_ADDRESS, "
        "JAX_NUM_PROCESSES, JAX_PROCESS_ID or the cluster's own environment)",
    )
    return p


def resolve_config(args):
    """The preset with the command line's overrides applied (ValueError on bad values)."""
    from mjx_peg.learn.config import PRESETS, prior_settings
    from mjx_peg.learn.run_dir import RunDir
    from mjx_peg.policy.export import load_policy
    from mjx_peg.policy.shipped import resolve_policy

    if args.seed is not None and args.seeds is not None:
        raise UsageError("--seed and --seeds: give one of them")
    overrides = {
        "engine": args.engine,
        "seed": args.seed,
        "num_envs": args.num_envs,
        "trials": args.trials,
        "time_limit_s": args.time_limit,
        "linear_mm": args.linear_mm,
        "angular_deg": args.angular_deg,
        "init_from": None if args.init_from is None else str(args.init_from),
        "full_time_limit": args.full_time_limit or None,
        "action_map": args.action_map,
        "grasp_model": args.grasp_model,
        "skill": args.skill,
        "eval_every": args.eval_every,
        "observation": args.observation,
        "parts": args.parts,
        "kl_target": args.kl_target,
        "std_decay": args.std_decay,
        "linear_per_size": True if args.parts else None,
    }
    config = PRESETS[args.preset].replace(**{k: v for k, v in overrides.items() if v is not None})
    if args.prior is not None:
        if args.prior == "none" and args.action_map == "centred":
            raise UsageError("--prior none starts mid-range under the sigmoid map; the centred "
                             "map is centred on the hand-tuned skill")  # fmt: skip
        start = prior_settings(args.prior, config.skill_constants)
        # what the command line sets itself wins over the start's settings
        config = config.replace(**{k: v for k, v in start.items() if overrides.get(k) is None})
    if args.skill_constant:
        config = config.replace(skill_constants=config.skill_constants.replace(
            **dict(args.skill_constant)))  # fmt: skip
    if args.fixed_skill or args.learn_skill:
        config = config.replace(learn_search=args.learn_skill)
    if args.preset == "transfer" and not config.init_from:
        raise UsageError("--preset transfer needs --init-from RUN_DIR (a finished run)")
    if config.init_from:
        config = config.replace(init_from=resolve_policy(config.init_from, "--init-from", False))
        load_policy(config.init_from)  # a finished run with a readable policy, or one clear line
        trained = RunDir(config.init_from).read_config()
        source = trained.action_map
        if args.action_map not in (None, source):
            raise UsageError(
                f"--action-map {args.action_map}: {config.init_from} was trained with the {source}"
                " map, and its networks mean that map's actions"
            )
        if args.observation not in (None, trained.observation):
            raise UsageError(
                f"--observation {args.observation}: {config.init_from} was trained on the "
                f"{trained.observation} layout, and its networks read that layout"
            )
        config = config.replace(init_from=os.path.abspath(config.init_from), action_map=source,
                                observation=trained.observation)  # fmt: skip
    return config


def join_distributed() -> None:
    """jax.distributed.initialize from JAX_COORDINATOR_ADDRESS / JAX_NUM_PROCESSES /
    JAX_PROCESS_ID when set, else from the cluster's environment (SLURM, ...)."""
    import jax

    def number(name):
        value = os.environ.get(name)
        try:
            return None if value is None else int(value)
        except ValueError:
            raise UsageError(f"{name}={value!r} is not an integer") from None

    try:
        jax.distributed.initialize(
            num_processes=number("JAX_NUM_PROCESSES"), process_id=number("JAX_PROCESS_ID")
        )
    except (RuntimeError, ValueError) as e:
        raise UsageError(f"--distributed: could not join the run ({e})") from None


def _writes_files(args) -> bool:
    """Whether this process writes the run directory (one of a --distributed run's does)."""
    if not args.distributed:
        return True
    import jax

    return jax.process_index() == 0


@cli.entry(PROG, "interrupted; rerun the same command to resume")
def main(argv=None) -> int:
    args = parser().parse_args(argv)
    out = args.out or Path("runs", args.preset)
    config = resolve_config(args)
    if config.iterations * config.num_envs != config.trials:
        cli.note(
            PROG,
            f"--trials {config.trials:,} rounded up to {config.iterations:,} iteration"
            f"{'s' * (config.iterations > 1)} of {config.num_envs:,} trials "
            f"({config.iterations * config.num_envs:,} trials)",
        )
    from mjx_peg.engines import resolve_engine

    engine = resolve_engine(config.engine)
    if args.ray is not None:
        options = cli.ray_options(args, engine, ("--threads",))
    else:
        options = {
            "threads": args.threads,
            "processes": cli.resolve_processes(args.processes, engine),
        }
        options = {k: v for k, v in options.items() if v is not None}
    if config.init_from:
        outdir.check_apart(out, {"--init-from": config.init_from})
    if args.distributed:
        join_distributed()  # before anything asks JAX for its devices
    cli.check_jax()
    import mjx_peg.learn.env  # noqa: F401  first: it imports brax with the Warp message muted
    from mjx_peg.learn.trainer import train
    from mjx_peg.world import mujoco_log

    mujoco_log.send_to(out)  # written only on a warning, once the run directory exists
    if args.ray is not None:  # join the cluster before the run directory is written
        from mjx_peg.engines import ray_pool

        signals.working()  # Ray starts processes: a signal stops them
        ray_pool.connect(args.ray)
    runs = [(config, out)]
    if args.seeds is not None:
        runs = [(config.replace(seed=seed), Path(out, f"seed-{seed}")) for seed in args.seeds]
    writes = _writes_files(args)
    # One writer per --out and per seed's run in it (with --distributed, the process that
    # writes the files holds them)
    with outdir.exclusive(out) if writes else contextlib.nullcontext():
        for run_config, run_out in runs:
            if len(runs) > 1 and not args.force and finished_run(run_config, run_out):
                cli.note(PROG, f"{run_out} is finished: skipped")
                continue
            held = outdir.exclusive(run_out) if writes and run_out != out else None
            with held or contextlib.nullcontext():
                summary = train(
                    run_config,
                    run_out,
                    force=args.force,
                    checkpoint_every_s=args.checkpoint_every,
                    progress=not args.no_progress,
                    engine_options=options,
                    note=lambda text: cli.note(PROG, text),
                    tensorboard=args.tensorboard,
                )
            print(summary.line())
    if len(runs) > 1:
        from mjx_peg.learn.seeds import summarize

        print(summarize(out))
    return 0


def finished_run(config, out) -> bool:
    """`out` holds a finished run of exactly `config` (a set of seeds skips it on a rerun)."""
    from mjx_peg.learn.run_dir import RunDir

    run = RunDir(out)
    return run.is_finished() and run.read_config() == config
