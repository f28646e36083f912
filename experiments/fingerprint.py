"""A fixed batch of trials on the C engine, every outcome kind, saved bit for bit: run it at two
commits and compare, to show a change left the trial's behaviour as it was.

    python experiments/fingerprint.py before.npz                  # at the old commit
    python experiments/fingerprint.py after.npz --compare before.npz

The batch: 48 trials (circle, square, triangle 50 mm, ±4 mm / ±6 deg, randomized sensor draws)
with the baseline's 38 numbers each scaled by U(0.8, 1.2), under seven trial configs (nominal,
protective stops at 60 N, loose settle tolerances, a 0.3 rad/s speed limit, every failure to the
limit, a 125 Hz / 25 Hz / 3-period sensor, the spiral skill), and 24 zero-error trials, all
but the spiral's with one skill (`--skill`, the paper's by default); `--compare` lists the arrays
that differ (exit 1 if any).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from mjx_peg.engines import mujoco as engine
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.skill import sensor
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.search import SKILLS, skill_config
from mjx_peg.world.task import TaskConfig, sample_trials

SHAPES = ("circle", "square", "triangle")


def variants(scale: float, skill: str = "paper") -> dict[str, TrialConfig]:
    """The trial configs of a named skill (skill.search.SKILLS), time limits times `scale`."""
    long, short = 12.0 * scale, 3.0 * scale
    configs = {
        "nominal": TrialConfig(time_limit_s=long),
        "stops": TrialConfig(time_limit_s=short, max_tool_force=60.0),
        "settles": TrialConfig(time_limit_s=long, settle_tip_m=1e-3, settle_force_n=5.0,
                               settle_moment_nm=0.5, settle_joint_speed=0.5),
        "unstable": TrialConfig(time_limit_s=short, max_joint_speed=0.3),
        "no_settle": TrialConfig(time_limit_s=long, end_settled=False),
        "slow_sensor": TrialConfig(time_limit_s=8.0 * scale, sensor=sensor.SensorConfig(
            rate_hz=125.0, cutoff_hz=25.0, delay_steps=3)),
        "spiral": TrialConfig(time_limit_s=long, search=skill_config("spiral")),
    }  # fmt: skip
    search = skill_config(skill)
    return {name: c if name == "spiral" else dataclasses.replace(c, search=search)
            for name, c in configs.items()}  # fmt: skip


def fingerprint(trials: int = 48, scale: float = 1.0, grasp_model: str = "flange",
                skill: str = "paper"):  # fmt: skip
    """{variant/field: array} of every TrialResult field of the batch."""
    task = TaskConfig(shapes=SHAPES, linear_error=0.004, angular_error=np.deg2rad(6.0),
                      sensor_cutoff_scale=(0.5, 2.0), sensor_noise_scale=(0.5, 2.0),
                      sensor_delay_offset=(-1, 2), grasp_model=grasp_model)  # fmt: skip
    specs = sample_trials(task, 3, trials)
    vector = np.asarray(baseline_params())
    scaled = np.tile(vector, (trials, 1)) * np.random.default_rng(0).uniform(0.8, 1.2, (trials, 38))
    params = as_controller_params(scaled, trials)
    out = {}
    for name, config in variants(scale, skill).items():
        result = engine.run_on_cpu(specs, params, config, threads=2)
        out.update({f"{name}/{k}": v for k, v in result.to_arrays().items()})
        print(f"{name}: {result.summary()}")
    zero = TaskConfig(shapes=SHAPES, linear_error=0.0, angular_error=0.0)
    n = max(1, trials // 2)
    result = engine.run_on_cpu(sample_trials(zero, 7, n), as_controller_params(vector, n),
                               TrialConfig(time_limit_s=8.0 * scale, search=skill_config(skill)),
                               threads=1)  # fmt: skip
    out.update({f"zero/{k}": v for k, v in result.to_arrays().items()})
    print(f"zero: {result.summary()}")
    return out


def _same(a, b, key: str) -> bool:
    if key not in a or key not in b:
        return False
    x, y = np.asarray(a[key]), np.asarray(b[key])
    return x.shape == y.shape and x.dtype == y.dtype and x.tobytes() == y.tobytes()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", help="npz to write")
    p.add_argument("--compare", help="an npz written before, to compare bit for bit")
    p.add_argument("--trials", type=int, default=48)
    p.add_argument("--time-scale", type=float, default=1.0, help="times every time limit")
    p.add_argument("--grasp-model", default="flange", choices=("flange", "board"),
                   help="where the grasp errors go (default flange: comparable with batches "
                   "saved before the board model existed)")  # fmt: skip
    p.add_argument(
        "--skill",
        default="paper",
        choices=tuple(SKILLS),
        help="the skill every trial runs (default paper: the paper's as written)",
    )
    args = p.parse_args(argv)
    arrays = fingerprint(args.trials, args.time_scale, args.grasp_model, args.skill)
    np.savez(args.out, **arrays)
    if args.compare is None:
        return 0
    with np.load(args.compare, allow_pickle=False) as other:
        names = sorted(set(other.files) | set(arrays))
        differ = [k for k in names if not _same(other, arrays, k)]
    print(f"{len(names) - len(differ)} of {len(names)} arrays bit-identical"
          + (f"; differ: {', '.join(differ)}" if differ else ""))  # fmt: skip
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
