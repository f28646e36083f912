"""One insertion watched: a trial on the C MuJoCo engine with its tip, wrench and frames recorded,
plotted as `trial.png` (tip height, lateral error of the tip from the hole axis and the wrench
the compliance sees over time) and a strip of rendered frames (`frames.png`). The command line
is `evaluation/demo_cli.py` (`mjx-peg-demo`).
"""

from __future__ import annotations

import pathlib

import numpy as np

from mjx_peg.engines.trial import TrialConfig
from mjx_peg.world import constants, scene
from mjx_peg.world.task import TrialSpec

MAX_FRAMES = 24  # frames in the strip (320 px each)
OUTPUTS = ("trial.png", "frames.png")


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

    result = engine.run_on_cpu(
        specs, params, config, threads=1, slots_per_thread=1, observer=observe
    )
    trace = {k: np.asarray(v) for k, v in trace.items()}
    if frames and last and (not snapshots or snapshots[-1][0] != last[0][0]):
        snapshots.append(last[0])
    return {"specs": specs, "result": result, "trace": trace, "snapshots": snapshots}


def plot_trial(run: dict, path: pathlib.Path) -> None:
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


def frame_strip(run: dict, frames: int) -> np.ndarray | None:
    """A strip of close-up frames around the hole at evenly spaced moments of the trial."""
    import mujoco

    from mjx_peg.world.render import render_rgb

    specs, snaps = run["specs"], run["snapshots"]
    if not snaps:
        return None
    shape = constants.SHAPES[int(specs.shape_id[0])]
    model = scene.load_model(shape, float(specs.size[0]), float(specs.hole_scale[0]))
    scene.set_board_pose(model, *specs.board_pos[0], specs.board_yaw[0],
                         specs.board_height[0], specs.board_tilt[0])  # fmt: skip
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
