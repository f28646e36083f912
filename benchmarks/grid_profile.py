"""Where a grid's time goes: one lane's stages on a grid's trials, and the physics by part.

    python benchmarks/grid_profile.py [--trials 2000] [--slots 512,128] [--physics-trials 80]

1. `policies/paper` with the spiral on `--trials` trials of circle and square 50 mm at +-4 mm /
   +-6 deg (60 s, early ending, as the grids run them) on one lane of `--slots` slots in this
   process, with the engine's profile hook (`lanes.PROFILE_STAGES`): µs per env-step by stage.
2. Bare `mj_step` on one hot MjData from snapshots of `--physics-trials` trials of the
   hand-tuned spiral at +-8 mm / +-12 deg (20 s), by part, under MuJoCo's collision options
   (`VARIANTS`): what a step of each part costs, and whether an option makes it cheaper.

Results: BENCHMARKS.md, "Where a grid's time goes, and what did not buy it back".
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import mujoco
import numpy as np
from physics import bare_steps  # benchmarks/ is on sys.path
from trials import profile_parts, record_states

from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.policy.export import load_policy
from mjx_peg.policy.shipped import resolve_policy
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.search import skill_config
from mjx_peg.world.constants import SHAPES
from mjx_peg.world.task import TaskConfig, sample_trials

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))
from ablations import chosen  # noqa: E402  (experiments/ablations.py: the policy's skill)


def _disable(bit):
    return lambda m: setattr(m.opt, "disableflags", m.opt.disableflags | bit)


VARIANTS = {
    "as shipped": lambda m: None,
    "ccd_iterations 10": lambda m: setattr(m.opt, "ccd_iterations", 10),
    "ccd_tolerance 1e-4": lambda m: setattr(m.opt, "ccd_tolerance", 1e-4),
    "libccd": _disable(mujoco.mjtDisableBit.mjDSBL_NATIVECCD),
    "mid-phase off": _disable(mujoco.mjtDisableBit.mjDSBL_MIDPHASE),
}


def lane_profile(trials: int, slots: int) -> list[str]:
    """µs per env-step by stage of one lane of `slots` on a grid's trials."""
    policy = load_policy(resolve_policy("paper"))
    task = TaskConfig(shapes=("circle", "square"), sizes=(0.05,), linear_error=0.004,
                      angular_error=math.radians(6.0))  # fmt: skip
    specs = sample_trials(task, 1, trials)
    params = as_controller_params(policy.controller_vectors(specs), trials)
    config = TrialConfig(time_limit_s=60.0, search=chosen(None, policy).config)
    return profile_parts(specs, params, config, True, slots=slots)


def physics_by_part(trials: int) -> dict[str, dict[str, float]]:
    """Mean µs per bare mj_step by part, per variant, from the spiral's snapshots."""
    task = TaskConfig(shapes=("circle", "square"), linear_error=0.008,
                      angular_error=math.radians(12.0))  # fmt: skip
    specs = sample_trials(task, 0, trials)
    config = TrialConfig(time_limit_s=20.0, end_settled=False, search=skill_config("spiral"))
    snaps = record_states(specs, as_controller_params(baseline_params(), trials), config, 200)
    parts = np.array([SHAPES[int(specs.shape_id[index])] for index, _, _ in snaps])
    out = {}
    for name, change in VARIANTS.items():
        micros = bare_steps(specs, snaps, change=change)[0][:, 1]
        out[name] = {part: float(micros[parts == part].mean()) for part in np.unique(parts)}
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=2000, help="trials of the lane's profile")
    p.add_argument("--slots", default="512,128", help="slots per lane, comma-separated")
    p.add_argument("--physics-trials", type=int, default=80, help="0 skips the physics part")
    args = p.parse_args()
    for slots in (int(x) for x in args.slots.split(",") if x):
        print(f"one lane of {slots} slots, {args.trials} grid trials, µs per env-step:")
        print("\n".join("  " + line for line in lane_profile(args.trials, slots)), flush=True)
    if args.physics_trials:
        print("bare mj_step, µs per step by part:")
        for name, parts in physics_by_part(args.physics_trials).items():
            print(f"  {name}: " + ", ".join(f"{k} {v:.2f}" for k, v in sorted(parts.items())))


if __name__ == "__main__":
    main()
