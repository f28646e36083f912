"""`mjx-peg-baseline`: the hand-tuned controller (skill/baseline.py) on sampled trials, per shape.

mjx-peg-baseline --linear-mm 3 --angular-deg 4 --trials 100   # per shape, 60 s limit
"""

from __future__ import annotations

from mjx_peg import cli, signals
from mjx_peg.skill.search import SKILL_DESCRIPTIONS
from mjx_peg.world import constants

PROG = "mjx-peg-baseline"


@cli.entry(PROG)
def main(argv=None) -> int:
    """Success and time of the hand-tuned baseline per shape at given errors."""
    from mjx_peg.engines import ENGINES
    from mjx_peg.world.parts import HOLE_SCALE_HELP, parse_hole_scale

    p = cli.Parser(prog=PROG, description=main.__doc__)
    p.add_argument(
        "--shapes",
        default=",".join(constants.PAPER_SHAPES),
        help=f"comma-separated, of {', '.join(constants.SHAPES)}",
    )
    p.add_argument("--size", type=cli.SIZE_MM, default=50.0, help="characteristic size S")
    p.add_argument("--hole-scale", default="paper", help=HOLE_SCALE_HELP)
    p.add_argument("--linear-mm", type=cli.LINEAR_MM, default=3.0, help="± linear error range")
    p.add_argument("--angular-deg", type=cli.ANGULAR_DEG, default=4.0, help="± angular error range")
    p.add_argument("--trials", type=cli.TRIALS, default=100, help="per shape (default 100)")
    p.add_argument(
        "--time-limit", type=cli.TIME_LIMIT_S, default=60.0, help="per trial (default 60)"
    )
    p.add_argument("--seed", type=cli.SEED, default=1, help="default 1")
    cli.add_grasp_model_option(p, constants.GRASP_MODELS, "board")
    cli.add_skill_option(p, SKILL_DESCRIPTIONS, "paper")
    p.add_argument("--engine", default="auto", choices=ENGINES)
    args = p.parse_args(argv)
    shapes = [s.strip() for s in args.shapes.split(",") if s.strip()]
    if not shapes:
        p.error(f"--shapes is empty: choose from {', '.join(constants.SHAPES)}")
    for shape in shapes:
        if shape not in constants.SHAPES:
            p.error(f"unknown shape {shape!r}: choose from {', '.join(constants.SHAPES)}")
    if len(set(shapes)) != len(shapes):
        p.error(f"--shapes names a shape twice: {args.shapes}")
    hole_scale = parse_hole_scale(args.hole_scale)
    from mjx_peg.engines import resolve_engine, run_trials
    from mjx_peg.engines.trial import TrialConfig
    from mjx_peg.skill.baseline import baseline_params
    from mjx_peg.skill.search import skill_config
    from mjx_peg.world.parts import fit_text
    from mjx_peg.world.task import TaskConfig, sample_trials

    config = TrialConfig(time_limit_s=args.time_limit, search=skill_config(args.skill))
    tasks = [
        TaskConfig.from_mm_deg(
            (shape,),
            args.size,
            args.linear_mm,
            args.angular_deg,
            grasp_model=args.grasp_model,
            hole_scale=hole_scale,
        )  # fmt: skip
        for shape in shapes
    ]
    from mjx_peg.world import mujoco_log

    mujoco_log.send_to(None)  # no output directory: MuJoCo's warnings go nowhere
    # Before working(): "auto" imports JAX and starts its backend to look for a GPU, and a signal
    # that unwound from there would leave its threads to crash the exit (SIGABRT)
    engine = resolve_engine(args.engine)
    signals.working()  # the engine starts worker processes: a signal stops them
    for shape, task in zip(shapes, tasks, strict=True):
        specs = sample_trials(task, args.seed, args.trials)
        result = run_trials(specs, baseline_params(), engine=engine, config=config)
        fit = fit_text(shape, task.hole_scale_range(shape)[0])
        print(
            f"{shape} {args.size:g} mm{fit} ±{args.linear_mm:g} mm ±{args.angular_deg:g} deg: "
            f"{result.summary()}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
