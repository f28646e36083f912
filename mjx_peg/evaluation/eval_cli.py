"""`python eval.py` (`mjx-peg-eval`): the command line of the evaluation grid.

    python eval.py --policy runs/quick --grid paper-small --out eval/quick

Parses and checks the flags, holds --out (`outdir.exclusive`), runs or resumes the grid and writes
its outputs; every rule of the grid itself lives in the evaluation's modules: `config` (the
grids), `eval_dir` (the output directory), `runner` (the trials), `report` (the outputs).
"""

from __future__ import annotations

import argparse
import inspect
import sys
import time
from collections.abc import Sequence

from mjx_peg import cli, outdir, signals
from mjx_peg.errors import UsageError

PROG = "eval.py"


def check_engine_options(engine: str, options: dict) -> None:
    """UsageError unless the engine's runner (`engines.engine_runner`) takes every option."""
    from mjx_peg.engines import engine_runner

    params = inspect.signature(engine_runner(engine)).parameters
    takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    for key in options:
        if key in ("specs", "params", "config", "progress") or not (takes_any or key in params):
            raise UsageError(f"the {engine} engine takes no option {key!r}")


def build_parser() -> argparse.ArgumentParser:
    from mjx_peg.cli import add_skill_constant_option
    from mjx_peg.engines import ENGINES
    from mjx_peg.evaluation.config import DEFAULT_SHAPES, GRIDS
    from mjx_peg.evaluation.paper_tables import PAPER_CONDITIONS
    from mjx_peg.evaluation.runner import DEFAULT_CHUNK_TRIALS
    from mjx_peg.skill.search import SKILL_DESCRIPTIONS
    from mjx_peg.skill.skill_cli import skill_constant
    from mjx_peg.world.constants import GRASP_MODELS, SHAPES
    from mjx_peg.world.parts import HOLE_SCALE_HELP

    p = cli.Parser(
        prog=PROG,
        description="Evaluate a policy over a grid of error ranges (paper section 6): grid.csv, "
        "heatmaps and summary.md in --out. Rerun the same command to resume.",
    )
    p.add_argument(
        "--policy",
        type=cli.nonempty_path,
        required=True,
        help="run directory with policy.npz, a shipped policy's name (quick, paper, "
        "transfer: policies/), or 'baseline'",
    )
    p.add_argument(
        "--out",
        type=cli.nonempty_path,
        required=True,
        help="output directory (an evaluation with the same options there is resumed)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="start over in --out although it holds an evaluation (another config, or finished): "
        "the earlier one is moved aside to OUT.replaced-DATE-TIME (nothing but an evaluation is "
        "ever replaced)",
    )
    p.add_argument(
        "--grid",
        default="paper-small",
        choices=GRIDS,
        help="paper: 25 x 14 ranges, N=200; paper-small: 10 x 10, N=50; custom",
    )
    p.add_argument(
        "--linear-mm",
        help="custom grid: linear ranges (mm), e.g. 0.5,1,2 or 1:8:1; each in [0, 50] mm, at "
        f"most {cli.MAX_AXIS:,} values",
    )
    p.add_argument(
        "--angular-deg",
        help="custom grid: angular ranges (deg), e.g. 2,6 or 2:12:2; each in [0, 45] deg, at "
        f"most {cli.MAX_AXIS:,} values",
    )
    p.add_argument(
        "--linear-absolute",
        action="store_true",
        help="preset grids: keep the linear ranges in mm instead of scaling with S/50mm",
    )
    p.add_argument(
        "--shape",
        default=",".join(DEFAULT_SHAPES),
        help=f"comma-separated shapes from {', '.join(SHAPES)} (trials split evenly)",
    )
    p.add_argument(
        "--size", type=cli.SIZE_MM, default=50.0, help="characteristic size S (default 50)"
    )
    p.add_argument("--hole-scale", default="paper", help=HOLE_SCALE_HELP)
    p.add_argument(
        "--trials",
        type=cli.TRIALS,
        help=f"trials per range (default: the grid's); at most {cli.MAX_GRID_TRIALS:,} in the grid",
    )
    p.add_argument(
        "--time-limit", type=cli.TIME_LIMIT_S, default=60.0, help="per trial, the paper's 60"
    )
    p.add_argument(
        "--full-time-limit",
        action="store_true",
        help="run every failure to the time limit, the paper's protocol (default: a failure "
        "that has settled, at rest or repeating the same motion, ends early; same outcome)",
    )
    cli.add_grasp_model_option(p, GRASP_MODELS, "board")
    cli.add_skill_option(p, SKILL_DESCRIPTIONS)
    add_skill_constant_option(p, skill_constant)
    p.add_argument("--seed", type=cli.SEED, default=0, help="default 0")
    p.add_argument("--engine", default="auto", choices=ENGINES)
    p.add_argument(
        "--threads", type=cli.integer(1, 64), help="engine option threads (if it takes it)"
    )
    cli.add_processes_option(p, "--threads")
    cli.add_ray_option(p)
    p.add_argument(
        "--chunk-trials",
        type=cli.TRIALS,
        default=DEFAULT_CHUNK_TRIALS,
        help="trials per engine call; results are saved after each",
    )
    p.add_argument(
        "--compare",
        type=cli.nonempty_path,
        metavar="OTHER_EVAL_DIR",
        help="test this evaluation against another one per quarter",
    )
    p.add_argument(
        "--alternative",
        default="less",
        choices=("less", "greater", "two-sided"),
        help="--compare: this success rate is less (generalization vs nominal) or "
        "greater (after vs before re-training) than the other's",
    )
    p.add_argument(
        "--paper",
        default="auto",
        choices=("auto", *PAPER_CONDITIONS, "none"),
        help="the paper's numbers to print beside ours (auto: by shape and size)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def config_from_args(args: argparse.Namespace, policy_label: str):
    """Resolve the CLI's options into an EvalConfig (ValueError on bad input)."""
    from mjx_peg.engines import resolve_engine
    from mjx_peg.evaluation.config import MAX_ERROR, EvalConfig, grid_axes
    from mjx_peg.policy.export import choose_skill
    from mjx_peg.world.constants import SHAPES
    from mjx_peg.world.parts import parse_hole_scale

    linear = None if args.linear_mm is None else cli.parse_ranges(args.linear_mm, "--linear-mm")
    angular = (
        None if args.angular_deg is None else cli.parse_ranges(args.angular_deg, "--angular-deg")
    )
    linear, angular, trials = grid_axes(
        args.grid, args.size, linear, angular, linear_absolute=args.linear_absolute
    )
    for flag, values, unit in (("--linear-mm", linear, "mm"), ("--angular-deg", angular, "deg")):
        lo, hi = MAX_ERROR[flag[2:].replace("-", "_")]
        bad = [v for v in values if not lo <= v <= hi]
        if bad:
            what = "ranges" if args.grid == "custom" else f"ranges of the {args.grid} grid at S"
            raise UsageError(f"{flag} {what} must lie in [{lo:g}, {hi:g}] {unit}, got {bad[0]:g}")
    trials = args.trials if args.trials is not None else trials
    if trials is None:
        raise UsageError("--grid custom needs --trials")
    n_ranges = len(set(linear)) * len(set(angular))
    if n_ranges > cli.MAX_RANGES:
        raise UsageError(
            f"{n_ranges:,} error ranges: an evaluation grid takes at most {cli.MAX_RANGES:,}"
        )
    if n_ranges * trials > cli.MAX_GRID_TRIALS:
        raise UsageError(
            f"{n_ranges:,} ranges x {trials:,} trials: an evaluation grid takes at most "
            f"{cli.MAX_GRID_TRIALS:,} trials"
        )
    shapes = tuple(s.strip() for s in args.shape.split(",") if s.strip())
    for shape in shapes:
        if shape not in SHAPES:
            raise UsageError(f"unknown shape {shape!r}: choose from {', '.join(SHAPES)}")
    skill = choose_skill(args.skill, args.policy)
    constants = skill.config
    if args.skill_constant:
        constants = constants.replace(**dict(args.skill_constant))
    hole_scale = parse_hole_scale(args.hole_scale)
    return EvalConfig(
        policy=policy_label,
        grid=args.grid,
        linear_mm=linear,
        angular_deg=angular,
        trials=trials,
        shapes=shapes,
        size_mm=args.size,
        time_limit_s=args.time_limit,
        full_time_limit=args.full_time_limit,
        grasp_model=args.grasp_model,
        skill=skill.name,
        skill_constants=constants,
        seed=args.seed,
        engine=resolve_engine(args.engine),
        hole_scale=None if hole_scale == "paper" else hole_scale,
    )


@cli.entry(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """`python eval.py`: run (or resume) an evaluation grid and write its outputs."""
    args = build_parser().parse_args(argv)
    from mjx_peg.evaluation.eval_dir import (
        GRID_FILE,
        PAPER_PNG,
        SUCCESS_PNG,
        SUMMARY_FILE,
        TIME_PNG,
        load_evaluation_grid,
        prepare_out_dir,
        range_path,
    )
    from mjx_peg.evaluation.paper_tables import paper_condition_for
    from mjx_peg.evaluation.report import write_outputs
    from mjx_peg.evaluation.runner import load_controller, run_evaluation
    from mjx_peg.policy.shipped import resolve_policy

    out = args.out
    policy = resolve_policy(args.policy)
    policy_label, controller = load_controller(policy)
    config = config_from_args(args, policy_label)
    if args.ray is not None:
        options = cli.ray_options(args, config.engine, ("--threads",))
    else:
        options = {"threads": args.threads} if args.threads else {}
        processes = cli.resolve_processes(args.processes, config.engine)
        if processes is not None:
            options["processes"] = processes
    check_engine_options(config.engine, options)
    try:
        other = None if args.compare is None else load_evaluation_grid(args.compare)
    except UsageError as exc:
        raise UsageError(f"--compare {exc}") from None
    paper_name = args.paper
    if paper_name == "auto":
        paper_fit = config.hole_scale is None
        paper_name = paper_condition_for(config.shapes, config.size_mm) if paper_fit else None
    elif paper_name == "none":
        paper_name = None
    outdir.check_apart(out, {"--policy": policy, "--compare": args.compare})
    outdir.check_out(out)
    if args.ray is not None:  # join the cluster before anything is written
        from mjx_peg.engines import ray_pool

        signals.working()  # Ray starts processes: a signal stops them
        ray_pool.connect(args.ray)
    with outdir.exclusive(out):  # from here a Ctrl-C keeps every finished range
        prepare_out_dir(
            out,
            config,
            None if policy == "baseline" else policy,
            force=args.force,
            note=lambda text: cli.note(PROG, text),
        )
        from mjx_peg.world import mujoco_log

        mujoco_log.send_to(out)
        n_ranges = len(config.ranges)
        start = time.perf_counter()
        try:
            ran = run_evaluation(
                config,
                out,
                controller,
                options,
                args.chunk_trials,
                show_progress=not args.no_progress,
            )
        except KeyboardInterrupt:
            done = sum(range_path(out, i).is_file() for i in range(n_ranges))
            print(
                f"eval.py: interrupted with {done} of {n_ranges} ranges saved in {out}; run the "
                "same command to resume",
                file=sys.stderr,
            )
            return cli.EXIT_INTERRUPTED
        label = policy_label if policy == "baseline" else f"{policy} ({policy_label[:19]})"
        write_outputs(out, config, label, paper_name, other, args.compare or "", args.alternative)
    wall = time.perf_counter() - start
    print(
        f"eval.py: {ran} trials run ({n_ranges * config.trials} in the grid) in {wall:.1f} s; "
        f"wrote {out / GRID_FILE}, {SUCCESS_PNG}, {TIME_PNG}, {SUMMARY_FILE}"
        + (f", {PAPER_PNG}" if paper_name is not None else "")
    )
    return 0
