"""Where the engines part: the contacts C MuJoCo and MJX find in the same jammed state.

    python experiments/contact_diff.py [--shape square] [--step 1000] [--count 3]

Runs the agreement experiment's specs (engines_agree.py defaults) on the mujoco engine, takes the
first `--count` failures of `--shape`, snapshots each one's MjData at `--step`, and evaluates that
same state with `mj_forward` and with `mjx.forward`. Prints per engine the contacts (position,
depth, and the position in both geoms' frames, in mm), the constraint forces and the joint
accelerations, so a difference in contact generation shows as points one engine has and the
other lacks.
"""

from __future__ import annotations

import argparse
import copy

import mujoco
import numpy as np
from engines_agree import agreement_specs  # experiments/ is on sys.path when run

from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.constants import SHAPES


def snapshots(specs, rows, step: int, config: TrialConfig) -> dict[int, tuple]:
    """{spec index: (MjModel, copy of MjData)} at `step` of each trial in `rows`."""
    taken = {}

    def observe(batch, live, wrench):
        for i in live:
            index = int(rows[batch.spec_index[i]])  # batch rows move as trials end
            if int(batch.step[i]) == step and index not in taken:
                m, d, _ = batch.current[i]  # copies, reused by the engine
                taken[index] = (copy.copy(m), copy.copy(d))

    run_trials(
        specs.take(rows), baseline_params(), engine="mujoco", config=config, threads=1,
        observer=observe,
    )  # fmt: skip
    return taken


def in_frame(d, geom: int, point) -> np.ndarray:
    """`point` (world, m) in geom's frame (mm)."""
    rot = np.asarray(d.geom_xmat[geom]).reshape(3, 3)
    return 1e3 * rot.T @ (np.asarray(point) - np.asarray(d.geom_xpos[geom]))


def show_contacts(name: str, d, pos, dist, geom) -> None:
    print(f"  {name}: {len(dist)} contacts")
    for p, depth, (g1, g2) in zip(pos, dist, geom, strict=True):
        print(
            f"    at {np.round(1e3 * p, 2)} mm, depth {1e3 * depth:.3f} mm, geoms {g1}-{g2}: "
            f"in {g1} {np.round(in_frame(d, g1, p), 2)}, in {g2} {np.round(in_frame(d, g2, p), 2)}"
        )


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--shape", default="square", choices=SHAPES)
    p.add_argument("--step", type=int, default=1000, help="physics step of the snapshot")
    p.add_argument("--count", type=int, default=3, help="failed trials to look at")
    p.add_argument("--trials", type=int, default=100)
    p.add_argument("--seed", type=int, default=11)
    p.add_argument("--time-limit", type=float, help="simulated s (default: 4 or twice --step)")
    args = p.parse_args(argv)
    from mujoco import mjx

    from mjx_peg.engines.mjx import jit

    specs = agreement_specs(args.trials, seed=args.seed)
    limit = args.time_limit or max(4.0, 2 * args.step * TrialConfig().timestep)
    config = TrialConfig(time_limit_s=limit)
    result = run_trials(specs, baseline_params(), engine="mujoco", config=config)
    failed = ~result.success & (specs.shape_id == SHAPES.index(args.shape))
    rows = np.flatnonzero(failed)[: args.count]
    if rows.size == 0:
        raise SystemExit(f"contact_diff.py: no failed {args.shape} trial among {args.trials}")
    forward = jit(mjx.forward)
    for index, (m, d) in sorted(snapshots(specs, rows, args.step, config).items()):
        print(f"trial {index} ({args.shape}) at step {args.step}:")
        mujoco.mj_forward(m, d)
        c = d.contact[: d.ncon]
        show_contacts("mujoco", d, c.pos, c.dist, c.geom)
        dx = mjx.get_data(m, forward(mjx.put_model(m), mjx.put_data(m, d)))
        con = dx.contact[: dx.ncon]  # the contacts MJX found, as an MjData holds them
        show_contacts("mjx", d, con.pos, con.dist, con.geom)
        for name in ("qfrc_constraint", "qacc"):
            print(f"  {name}: mujoco {np.round(getattr(d, name), 2)}")
            print(f"  {' ' * len(name)}  mjx    {np.round(getattr(dx, name), 2)}")


if __name__ == "__main__":
    main()
