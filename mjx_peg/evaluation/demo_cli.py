"""Watch one insertion: `mjx-peg-demo --shape square --size 50 --linear-mm 3 ...`.

Runs one trial with the hand-tuned baseline or a learned policy (`--policy RUN_DIR`) on the
C MuJoCo engine and writes, into --out: `trial.png` (tip height, lateral error of the tip from the
hole axis and the wrench the compliance sees over time) and `frames.png` (a strip of rendered
frames).

`--replay EVAL_DIR --range R --trial K` replays one trial of an evaluation instead: the same
spec, policy and time limit, so a failure found in a grid can be watched. It checks that the
replay ends as the evaluation recorded (exit 1 if not).

    python -m mjx_peg.evaluation.demo_cli --replay runs/eval/nominal --range 300 --trial failure
"""

from __future__ import annotations

import argparse
import pathlib
import sys

from mjx_peg import cli, outdir
from mjx_peg.errors import UsageError
from mjx_peg.policy.shipped import resolve_policy
from mjx_peg.world import constants

PROG = "mjx-peg-demo"
_DEFAULTS = {
    "shape": "square",
    "size": 50.0,
    "hole_scale": "paper",
    "linear_mm": 3.0,
    "angular_deg": 4.0,
    "seed": 0,
    "time_limit": 10.0,
    "policy": "baseline",
}


def build_parser() -> argparse.ArgumentParser:
    from mjx_peg.evaluation.demo import MAX_FRAMES, OUTPUTS
    from mjx_peg.world.parts import HOLE_SCALE_HELP

    p = cli.Parser(prog=PROG, description=__doc__.splitlines()[0])
    d = _DEFAULTS
    p.add_argument("--shape", choices=constants.SHAPES, help=f"default {d['shape']}")
    p.add_argument(
        "--size", type=cli.SIZE_MM, help=f"characteristic size S (default {d['size']:g})"
    )
    p.add_argument("--hole-scale", help=HOLE_SCALE_HELP)
    p.add_argument(
        "--linear-mm",
        type=cli.LINEAR_MM,
        help=f"± linear error range (default {d['linear_mm']:g})",
    )
    p.add_argument(
        "--angular-deg",
        type=cli.ANGULAR_DEG,
        help=f"± angular error range (default {d['angular_deg']:g})",
    )
    p.add_argument("--seed", type=cli.SEED, help=f"default {d['seed']}")
    p.add_argument(
        "--time-limit",
        type=cli.TIME_LIMIT_S,
        help=f"simulated time (default {d['time_limit']:g})",
    )
    p.add_argument(
        "--policy",
        type=str,
        help="RUN_DIR holding policy.npz, a shipped policy's name (policies/), or baseline (the "
        "default)",
    )
    p.add_argument(
        "--replay",
        type=cli.nonempty_path,
        metavar="EVAL_DIR",
        help="replay a trial of this evaluation (its spec, policy and time limit)",
    )
    p.add_argument(
        "--range",
        type=cli.integer(0, cli.MAX_RANGES - 1),
        help="with --replay: the range (grid.csv's first column)",
    )
    p.add_argument(
        "--trial",
        default="0",
        help="with --replay: trial index in the range, or 'failure' / 'success' for "
        "the range's first such trial (default 0)",
    )
    p.add_argument(
        "--frames", type=cli.integer(0, MAX_FRAMES), default=6, help="frames in the strip (0: none)"
    )
    p.add_argument("--out", type=cli.nonempty_path, default=pathlib.Path("demo_out"))
    p.add_argument(
        "--force",
        action="store_true",
        help=f"replace {' and '.join(OUTPUTS)} in --out: the earlier ones are moved aside "
        "(NAME.replaced-DATE-TIME)",
    )
    return p


def _controller(policy: str):
    from mjx_peg.evaluation.runner import load_controller

    return load_controller(policy)


def trial_from_args(args):
    """(one spec, its (1, 38) controller vector, trial config, label) from the trial options."""
    from mjx_peg.engines.trial import TrialConfig
    from mjx_peg.policy.export import policy_skill
    from mjx_peg.world.parts import fit_text, parse_hole_scale
    from mjx_peg.world.task import TaskConfig, sample_trials

    for dest, value in _DEFAULTS.items():
        if getattr(args, dest) is None:
            setattr(args, dest, value)
    if not args.policy:
        raise UsageError("--policy must be a run directory or baseline, got an empty string")
    args.policy = resolve_policy(args.policy)
    task = TaskConfig.from_mm_deg((args.shape,), args.size, args.linear_mm, args.angular_deg,
                                  hole_scale=parse_hole_scale(args.hole_scale))  # fmt: skip
    specs = sample_trials(task, args.seed, 1)
    _, controller = _controller(args.policy)
    label = (f"{args.shape} {args.size:g} mm{fit_text(args.shape, specs.hole_scale[0])}, "
             f"±{args.linear_mm:g} mm / ±{args.angular_deg:g} deg")  # fmt: skip
    search = policy_skill(args.policy).config  # the skill its manifest names
    return specs, controller(specs), TrialConfig(args.time_limit, search=search), label


def trial_from_eval(args):
    """Like `trial_from_args` for trial --trial of range --range of the evaluation --replay,
    plus what the evaluation recorded for that trial."""
    import numpy as np

    from mjx_peg.evaluation import config as eval_config
    from mjx_peg.evaluation import eval_dir

    given = ["--" + k.replace("_", "-") for k in _DEFAULTS if getattr(args, k) is not None]
    if given:
        raise UsageError(f"--replay takes the trial from the evaluation; drop {', '.join(given)}")
    config, policy_dir = eval_dir.read_eval_dir(args.replay)
    n_ranges = len(config.ranges)
    if args.range is None or not 0 <= args.range < n_ranges:
        raise UsageError(f"--replay needs --range between 0 and {n_ranges - 1}, got {args.range}")
    recorded = eval_dir.load_range(pathlib.Path(args.replay), config, args.range)
    if recorded is None:
        raise UsageError(f"range {args.range} of {args.replay} has not finished")
    if args.trial in ("failure", "success"):
        hits = np.flatnonzero(recorded["success"] == (args.trial == "success"))
        if hits.size == 0:
            raise UsageError(f"range {args.range} of {args.replay} has no {args.trial}")
        index = int(hits[0])
    elif args.trial.isdigit() and int(args.trial) < config.trials:
        index = int(args.trial)
    else:
        raise UsageError(
            f"--trial must be failure, success or an index below {config.trials}, "
            f"got {args.trial!r}"
        )
    if config.contact_model < eval_config.CONTACT_MODEL:
        raise UsageError(
            f"{args.replay} was evaluated before credible contact (another trial: no F/T "
            "pipeline, no protective stop); it cannot be replayed"
        )
    if config.policy == "baseline":
        policy = "baseline"
    elif policy_dir is None:
        raise UsageError(f"{args.replay}/config.json does not say where its policy is")
    else:
        policy = policy_dir
    label, controller = _controller(policy)
    if label != config.policy:
        raise UsageError(
            f"{policy}/policy.npz has changed since the evaluation ({config.policy[:19]})"
        )
    specs = eval_config.range_specs(config, args.range)
    params = controller(specs)[index : index + 1]  # the whole range, as the evaluation computed it
    linear_mm, angular_deg = config.ranges[args.range]
    shape = constants.SHAPES[int(specs.shape_id[index])]
    text = (
        f"{args.replay} range {args.range} (±{linear_mm:g} mm / ±{angular_deg:g} deg) trial "
        f"{index}: {shape} {config.size_mm:g} mm, policy {policy}"
    )
    trial = {k: recorded[k][index] for k in ("success", "time_s", "steps")}
    trial["engine"] = config.engine
    return specs.take([index]), params, config.trial_config(), text, trial


def _outcome(success, time_s) -> str:
    return f"{'success' if success else 'failure'} after {float(time_s):.3f} s"


@cli.entry(PROG)
def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from mjx_peg.evaluation.demo import OUTPUTS, frame_strip, plot_trial, run_demo

    if args.replay is None:
        if args.range is not None or args.trial != "0":
            raise UsageError("--range and --trial need --replay EVAL_DIR")
        specs, vector, config, label = trial_from_args(args)
        recorded = None
    else:
        specs, vector, config, label, recorded = trial_from_eval(args)
    # The output location, before any work: never an input, nothing replaced without --force.
    policy = None if args.replay is not None else args.policy
    outdir.check_apart(args.out, {"--policy": policy, "--replay": args.replay})
    with outdir.exclusive(args.out):
        outputs = [args.out / name for name in OUTPUTS[: 2 if args.frames else 1]]
        if args.out.is_dir() and not args.force:
            outdir.refuse_or_move(outputs, False)
        if args.frames:
            from mjx_peg.world import render

            render.check_backend()  # or one line: before the trial runs
        outdir.prepare_dir(args.out)
        outdir.refuse_or_move(outputs, args.force, lambda text: cli.note(PROG, text))
        if args.frames:
            from mjx_peg.world import gl

            if gl.fallback_note():
                cli.note(PROG, f"warning: {gl.fallback_note()}")
        from mjx_peg.world import mujoco_log

        mujoco_log.send_to(args.out)
        run = run_demo(specs, vector, config, args.frames)
        files = [(outputs[0], lambda path: plot_trial(run, path))]
        strip = frame_strip(run, args.frames) if args.frames else None
        if strip is not None:
            from mjx_peg.world.render import save_png

            files.append((outputs[1], lambda path: save_png(path, strip)))
        wrote = [p.name for p in outdir.write_all_atomic(files)]  # both or neither
    print(f"{label}: {run['result'].summary()}; wrote {' and '.join(wrote)} in {args.out}")
    if recorded is None:
        return 0
    r = run["result"]
    now = _outcome(r.success[0], r.time_s[0])
    then = _outcome(recorded["success"], recorded["time_s"])
    same = now == then and int(r.steps[0]) == int(recorded["steps"])
    engine = "" if recorded["engine"] == "mujoco" else f" on {recorded['engine']}"
    print(f"replay: {now}; the evaluation{engine}: {then} ({'the same' if same else 'DIFFERENT'})")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
