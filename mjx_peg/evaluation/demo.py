"""Watch one insertion: `mjx-peg-demo --shape square --size 50 --linear-mm 3 ...`.

Runs one trial with the hand-tuned baseline or a learned policy (`--policy RUN_DIR`) on the
C MuJoCo engine and writes, into --out: `trial.png` (tip height, lateral error of the tip from the
hole axis and the wrench the compliance sees over time) and `frames.png` (a strip of rendered
frames).

`--replay EVAL_DIR --range R --trial K` replays one trial of an evaluation instead: the same
spec, policy and time limit, so a failure found in a grid can be watched. It checks that the
replay ends as the evaluation recorded (exit 1 if not).

    python -m mjx_peg.evaluation.demo --replay runs/eval/nominal --range 300 --trial failure
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

from mjx_peg import cli
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.world import constants, scene
from mjx_peg.world.task import TaskConfig, TrialSpec, sample_trials

# The trial options (argparse dest -> default); --replay takes them from the evaluation.
PROG = "mjx-peg-demo"
_DEFAULTS = {
    "shape": "square",
    "size": 50.0,
    "linear_mm": 3.0,
    "angular_deg": 4.0,
    "seed": 0,
    "time_limit": 10.0,
    "policy": "baseline",
}


MAX_FRAMES = 24  # frames in the strip (320 px each)
OUTPUTS = ("trial.png", "frames.png")


def _parser() -> argparse.ArgumentParser:
    p = cli.Parser(prog=PROG, description=__doc__.splitlines()[0])
    d = _DEFAULTS
    p.add_argument("--shape", choices=constants.SHAPES, help=f"default {d['shape']}")
    p.add_argument(
        "--size", type=cli.SIZE_MM, help=f"characteristic size S (default {d['size']:g})"
    )
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
        help="RUN_DIR holding policy.npz, or baseline (the default)",
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
    from mjx_peg.evaluation.grid import load_controller

    return load_controller(policy)


def trial_from_args(args) -> tuple[TrialSpec, np.ndarray, TrialConfig, str]:
    """(one spec, its (1, 38) controller vector, trial config, label) from the trial options."""
    for dest, value in _DEFAULTS.items():
        if getattr(args, dest) is None:
            setattr(args, dest, value)
    if not args.policy:
        raise ValueError("--policy must be a run directory or baseline, got an empty string")
    task = TaskConfig.from_mm_deg((args.shape,), args.size, args.linear_mm, args.angular_deg)
    specs = sample_trials(task, args.seed, 1)
    _, controller = _controller(args.policy)
    label = f"{args.shape} {args.size:g} mm, ±{args.linear_mm:g} mm / ±{args.angular_deg:g} deg"
    return specs, controller(specs), TrialConfig(time_limit_s=args.time_limit), label


def trial_from_eval(args) -> tuple[TrialSpec, np.ndarray, TrialConfig, str, dict]:
    """Like `trial_from_args` for trial --trial of range --range of the evaluation --replay,
    plus what the evaluation recorded for that trial."""
    from mjx_peg.evaluation import grid as evaluation

    given = ["--" + k.replace("_", "-") for k in _DEFAULTS if getattr(args, k) is not None]
    if given:
        raise ValueError(f"--replay takes the trial from the evaluation; drop {', '.join(given)}")
    config, policy_dir = evaluation.read_eval_dir(args.replay)
    n_ranges = len(config.ranges)
    if args.range is None or not 0 <= args.range < n_ranges:
        raise ValueError(f"--replay needs --range between 0 and {n_ranges - 1}, got {args.range}")
    recorded = evaluation.load_range(pathlib.Path(args.replay), config, args.range)
    if recorded is None:
        raise ValueError(f"range {args.range} of {args.replay} has not finished")
    if args.trial in ("failure", "success"):
        hits = np.flatnonzero(recorded["success"] == (args.trial == "success"))
        if hits.size == 0:
            raise ValueError(f"range {args.range} of {args.replay} has no {args.trial}")
        index = int(hits[0])
    elif args.trial.isdigit() and int(args.trial) < config.trials:
        index = int(args.trial)
    else:
        raise ValueError(
            f"--trial must be failure, success or an index below {config.trials}, "
            f"got {args.trial!r}"
        )
    if config.contact_model < evaluation.CONTACT_MODEL:
        raise ValueError(
            f"{args.replay} was evaluated before credible contact (another trial: no F/T "
            "pipeline, no protective stop); it cannot be replayed"
        )
    if config.policy == "baseline":
        policy = "baseline"
    elif policy_dir is None:
        raise ValueError(f"{args.replay}/config.json does not say where its policy is")
    else:
        policy = policy_dir
    label, controller = _controller(policy)
    if label != config.policy:
        raise ValueError(
            f"{policy}/policy.npz has changed since the evaluation ({config.policy[:19]})"
        )
    specs = evaluation.range_specs(config, args.range)
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


def run_demo(specs: TrialSpec, vector: np.ndarray, config: TrialConfig, frames: int) -> dict:
    """Run one trial on the C MuJoCo engine, recording the tip, the wrench and snapshots."""
    from mjx_peg.engines import mujoco as engine
    from mjx_peg.engines.trial import as_controller_params

    params = as_controller_params(vector, 1)
    every = max(1, int(round(0.25 / config.timestep)))
    trace = {"t": [], "tip": [], "wrench": []}
    snapshots, last = [], []

    def observe(worker, rows, wrench):
        step = int(worker.step[0])
        trace["t"].append(step * config.timestep)
        trace["tip"].append(worker.tip_pos[0].copy())
        trace["wrench"].append(wrench[0].copy())
        last[:] = [(step * config.timestep, worker.qpos[0])]
        if frames and step % every == 0:
            snapshots.append(last[0])

    result = engine.run_trials(
        specs, params, config, threads=1, slots_per_thread=1, observer=observe
    )
    trace = {k: np.asarray(v) for k, v in trace.items()}
    if frames and last and (not snapshots or snapshots[-1][0] != last[0][0]):
        snapshots.append(last[0])
    return {"specs": specs, "result": result, "trace": trace, "snapshots": snapshots}


def _plot(run: dict, path: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, tip, wrench = run["trace"]["t"], run["trace"]["tip"], run["trace"]["wrench"]
    hole = run["specs"].board_pos[0]
    fig, ax = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
    ax[0].plot(t, tip[:, 2] * 1000)
    ax[0].axhline(constants.HOLE_DEPTH * 1000, color="gray", ls="--", label="board top")
    ax[0].axhline(20, color="green", ls=":", label="success (20 mm)")
    ax[0].set_ylabel("tip height (mm)")
    ax[0].legend(loc="upper right")
    ax[1].plot(t, np.linalg.norm(tip[:, :2] - hole, axis=1) * 1000)
    ax[1].set_ylabel("tip to hole axis (mm)")
    for i, name in enumerate(("Fx", "Fy", "Fz")):
        ax[2].plot(t, wrench[:, i], label=name)
    ax[2].set_ylabel("sensed force, damped, goal frame (N)")
    ax[2].set_xlabel("time (s)")
    ax[2].legend(loc="upper right")
    r = run["result"]
    fig.suptitle(f"{'success' if r.success[0] else 'failure'} after {r.time_s[0]:.2f} s")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _frames(run: dict, frames: int) -> np.ndarray | None:
    """A strip of close-up frames around the hole at evenly spaced moments of the trial."""
    import mujoco

    from mjx_peg.world.render import render_rgb

    specs, snaps = run["specs"], run["snapshots"]
    if not snaps:
        return None
    model = scene.load_model(constants.SHAPES[int(specs.shape_id[0])], float(specs.size[0]))
    scene.set_board_pose(model, *specs.board_pos[0], specs.board_yaw[0])
    scene.set_grasp(model, *specs.grasp_error[0])
    data = mujoco.MjData(model)
    camera = mujoco.MjvCamera()
    camera.lookat[:] = (*specs.board_pos[0], constants.HOLE_DEPTH + 0.03)
    camera.distance, camera.elevation, camera.azimuth = 0.45, -25.0, 200.0
    picks = np.linspace(0, len(snaps) - 1, min(frames, len(snaps))).round().astype(int)
    tiles = []
    for i in picks:
        _, qpos = snaps[i]
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        tiles.append(render_rgb(model, data, camera, 320, 320))
    return np.concatenate(tiles, axis=1)


def _outcome(success, time_s) -> str:
    return f"{'success' if success else 'failure'} after {float(time_s):.3f} s"


@cli.entry(PROG)
def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    if args.replay is None:
        if args.range is not None or args.trial != "0":
            raise ValueError("--range and --trial need --replay EVAL_DIR")
        specs, vector, config, label = trial_from_args(args)
        recorded = None
    else:
        specs, vector, config, label, recorded = trial_from_eval(args)
    # The output location, before any work: never an input, nothing replaced without --force.
    policy = None if args.replay is not None else args.policy
    cli.check_apart(args.out, {"--policy": policy, "--replay": args.replay})
    outputs = [args.out / name for name in OUTPUTS[: 2 if args.frames else 1]]
    if args.out.is_dir() and not args.force:
        cli.refuse_or_move(outputs, False, PROG)
    if args.frames:
        from mjx_peg.world import render

        render.check_backend()  # or one line: before the trial runs
    cli.prepare_dir(args.out)
    cli.refuse_or_move(outputs, args.force, PROG)
    if args.frames:
        from mjx_peg.world import gl

        if gl.fallback_note():
            cli.note(PROG, f"warning: {gl.fallback_note()}")
    from mjx_peg.world import mujoco_log

    mujoco_log.send_to(args.out)
    run = run_demo(specs, vector, config, args.frames)
    cli.write_atomic(outputs[0], lambda path: _plot(run, path))
    wrote = [outputs[0].name]
    strip = _frames(run, args.frames) if args.frames else None
    if strip is not None:
        from mjx_peg.world.render import save_png

        cli.write_atomic(outputs[1], lambda path: save_png(path, strip))
        wrote.append(outputs[1].name)
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
