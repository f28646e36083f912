"""Watch one insertion: `python -m mjx_peg.demo --shape square --size 50 --linear-mm 3 ...`.

Runs one trial with the hand-tuned baseline (or a 38-vector of parameters from a .npz) on the
C MuJoCo engine and writes, into --out: `trial.png` (tip height, lateral error of the tip from the
hole axis and the contact wrench over time) and `frames.png` (a strip of rendered frames).
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

import numpy as np

from mjx_peg import scene
from mjx_peg.baseline import baseline_params
from mjx_peg.task import TaskConfig, sample_trials
from mjx_peg.trial import TrialConfig


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m mjx_peg.demo", description=__doc__.splitlines()[0])
    p.add_argument("--shape", default="square", choices=scene.SHAPES)
    p.add_argument("--size", type=float, default=50.0, help="characteristic size S in mm")
    p.add_argument("--linear-mm", type=float, default=3.0, help="± linear error range (mm)")
    p.add_argument("--angular-deg", type=float, default=4.0, help="± angular error range (deg)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--time-limit", type=float, default=10.0, help="simulated seconds")
    p.add_argument("--frames", type=int, default=6, help="frames in the strip (0: none)")
    p.add_argument("--out", type=pathlib.Path, default=pathlib.Path("demo_out"))
    return p


def run_demo(args) -> dict:
    from mjx_peg.engines import mujoco as engine
    from mjx_peg.trial import as_controller_params

    task = TaskConfig(
        shapes=(args.shape,),
        sizes=(args.size / 1000.0,),
        linear_error=args.linear_mm / 1000.0,
        angular_error=np.deg2rad(args.angular_deg),
    )
    specs = sample_trials(task, args.seed, 1)
    config = TrialConfig(time_limit_s=args.time_limit)
    params = as_controller_params(baseline_params(), 1)
    every = max(1, int(round(0.25 / config.timestep)))
    trace = {"t": [], "tip": [], "wrench": []}
    snapshots, last = [], []

    def observe(worker, rows, wrench):
        step = int(worker.step[0])
        trace["t"].append(step * config.timestep)
        trace["tip"].append(worker.tip_pos[0].copy())
        trace["wrench"].append(wrench[0].copy())
        _, d, _ = worker.current[0]
        last[:] = [(step * config.timestep, d.qpos.copy())]
        if args.frames and step % every == 0:
            snapshots.append(last[0])

    result = engine.run_trials(
        specs, params, config, threads=1, slots_per_thread=1, observer=observe
    )
    trace = {k: np.asarray(v) for k, v in trace.items()}
    if args.frames and last and (not snapshots or snapshots[-1][0] != last[0][0]):
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
    ax[0].axhline(scene.HOLE_DEPTH * 1000, color="gray", ls="--", label="board top")
    ax[0].axhline(20, color="green", ls=":", label="success (20 mm)")
    ax[0].set_ylabel("tip height (mm)")
    ax[0].legend(loc="upper right")
    ax[1].plot(t, np.linalg.norm(tip[:, :2] - hole, axis=1) * 1000)
    ax[1].set_ylabel("tip to hole axis (mm)")
    for i, name in enumerate(("Fx", "Fy", "Fz")):
        ax[2].plot(t, wrench[:, i], label=name)
    ax[2].set_ylabel("contact force, goal frame (N)")
    ax[2].set_xlabel("time (s)")
    ax[2].legend(loc="upper right")
    r = run["result"]
    fig.suptitle(f"{'success' if r.success[0] else 'failure'} after {r.time_s[0]:.2f} s")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _frames(run: dict, args, path: pathlib.Path) -> None:
    """A strip of close-up frames around the hole at evenly spaced moments of the trial."""
    import mujoco

    from mjx_peg.render import render_rgb, save_png

    specs, snaps = run["specs"], run["snapshots"]
    if not snaps:
        return
    model = scene.load_model(args.shape, args.size / 1000.0)
    scene.set_board_pose(model, *specs.board_pos[0], specs.board_yaw[0])
    scene.set_grasp(model, *specs.grasp_error[0])
    data = mujoco.MjData(model)
    camera = mujoco.MjvCamera()
    camera.lookat[:] = (*specs.board_pos[0], scene.HOLE_DEPTH + 0.03)
    camera.distance, camera.elevation, camera.azimuth = 0.45, -25.0, 200.0
    picks = np.linspace(0, len(snaps) - 1, min(args.frames, len(snaps))).round().astype(int)
    tiles = []
    for i in picks:
        _, qpos = snaps[i]
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        tiles.append(render_rgb(model, data, camera, 320, 320))
    save_png(path, np.concatenate(tiles, axis=1))


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    if not (args.size > 0 and np.isfinite(args.size)):
        _parser().error(f"--size must be a positive number of mm, got {args.size}")
    if args.linear_mm < 0 or args.angular_deg < 0:
        _parser().error("error ranges must be >= 0")
    if args.time_limit <= 0:
        _parser().error("--time-limit must be positive")
    os.environ.setdefault("MUJOCO_GL", "egl")
    args.out.mkdir(parents=True, exist_ok=True)
    run = run_demo(args)
    _plot(run, args.out / "trial.png")
    _frames(run, args, args.out / "frames.png")
    print(
        f"{args.shape} {args.size:g} mm, ±{args.linear_mm:g} mm / ±{args.angular_deg:g} deg: "
        f"{run['result'].summary()}; wrote {args.out}/trial.png and frames.png"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
