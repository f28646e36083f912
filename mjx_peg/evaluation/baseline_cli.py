"""`mjx-peg-baseline`: the hand-tuned controller (skill/baseline.py) on sampled trials, per shape.

mjx-peg-baseline --linear-mm 3 --angular-deg 4 --trials 100   # per shape, 60 s limit
"""

from __future__ import annotations

from mjx_peg import cli
from mjx_peg.engines import ENGINES, run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world import constants
from mjx_peg.world.task import TaskConfig, sample_trials

PROG = "mjx-peg-baseline"


def main(argv=None) -> int:
    """Success and time of the hand-tuned baseline per shape at given errors."""
    p = cli.Parser(prog=PROG, description=main.__doc__)
    p.add_argument("--shapes", default="circle,square,triangle")
    p.add_argument("--size", type=float, default=50.0, help="characteristic size (mm)")
    p.add_argument("--linear-mm", type=float, default=3.0)
    p.add_argument("--angular-deg", type=float, default=4.0)
    p.add_argument("--trials", type=int, default=100)
    p.add_argument("--time-limit", type=float, default=60.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--engine", default="auto", choices=ENGINES)
    args = p.parse_args(argv)
    shapes = args.shapes.split(",")
    for shape in shapes:
        if shape not in constants.SHAPES:
            p.error(f"unknown shape {shape!r}: choose from {', '.join(constants.SHAPES)}")
    if args.trials <= 0:
        p.error("--trials must be positive")
    try:
        config = TrialConfig(time_limit_s=args.time_limit)
        for shape in shapes:
            task = TaskConfig.from_mm_deg((shape,), args.size, args.linear_mm, args.angular_deg)
            specs = sample_trials(task, args.seed, args.trials)
            result = run_trials(specs, baseline_params(), engine=args.engine, config=config)
            print(
                f"{shape} {args.size:g} mm ±{args.linear_mm:g} mm ±{args.angular_deg:g} deg: "
                f"{result.summary()}"
            )
    except cli.USER_ERRORS as exc:
        return cli.fail(PROG, exc)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
