"""Success and contact metrics of a controller on a fixed set of trials.

    python experiments/contact.py [--policy baseline|RUN_DIR] [--sensor VARIANT] [--trials 500]
        [--time-limit 60] [--seed 1] [--first] [--full-time-limit] [--threads N]
        [--processes N] [--pass numpy|compiled] [--indices FILE] [--csv FILE]

The set: circle + square 50 mm (`--shapes`, `--size-mm`), +-4 mm / +-6 deg,
`sample_trials(seed)`, on the C engine with the default TrialConfig (failures that have settled
end early unless --full-time-limit). Prints the outcome summary (success, protective stops,
settled failures, peak sensed force, chatter), the time to insert, the physics steps per second
and the failure taxonomy (`mjx_peg.evaluation.taxonomy`). `--first`: the first hand-tuned
baseline instead of the current one; `--policy RUN_DIR`: a trained policy. `--sensor` changes
one thing of every trial's F/T pipeline (`SENSOR_VARIANTS`); `--friction F` gives every trial
the friction F. `--indices FILE`: only those of the trials (one index per line; the CSV keeps
their indices). `--pass`: the control period's pass (`run_trials(compiled=...)`; default the
engine's). `--csv`: one row per trial, for paired comparisons (`experiments/contact_table.py`).
Why these trials: docs/design/credible_contact.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import time

import numpy as np
from ablations import ablation, add_skill_option, chosen  # experiments/ablations.py

from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.evaluation import taxonomy
from mjx_peg.policy.export import load_policy
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.params import PARAM_NAMES, ControllerParams, vector_from_controller
from mjx_peg.skill.sensor import SensorConfig
from mjx_peg.skill.skill_cli import skill_constant
from mjx_peg.world.constants import GRASP_MODELS, HOLE_DEPTH
from mjx_peg.world.task import TaskConfig, sample_trials


def first_baseline() -> np.ndarray:
    """(38,) the first hand-tuned baseline: k = 300, compliance 1e-3 m/N and 0.05 rad/(N m),
    +-3e-3 m/(N m) moment-to-shift."""
    c = np.diag([1e-3, 1e-3, 1e-3, 0.05, 0.05, 0.01])
    c[1, 3], c[0, 4] = 3e-3, -3e-3
    k = np.asarray(300.0)
    return np.asarray(vector_from_controller(ControllerParams(k, k, c)))


def sensor_variant(name: str) -> SensorConfig:
    """The nominal UR5e pipeline with one thing changed: no low-pass, the cutoff halved or
    doubled, two more periods of latency, the noise doubled."""
    s = SensorConfig()
    return {
        "nominal": s,
        "nofilter": s.replace(cutoff_hz=math.inf),
        "cutoff0.5": s.replace(cutoff_hz=s.cutoff_hz * 0.5),
        "cutoff2": s.replace(cutoff_hz=s.cutoff_hz * 2.0),
        "delay+2": s.replace(delay_steps=s.delay_steps + 2),
        "noise2": s.replace(force_noise=2 * s.force_noise, torque_noise=2 * s.torque_noise),
    }[name]


SENSOR_VARIANTS = ("nominal", "nofilter", "cutoff0.5", "cutoff2", "delay+2", "noise2")


def write_csv(path: str, result, specs, indices=None) -> None:
    """One row per trial (`indices`: their numbers, default 0..); where the peg tip ended: its
    depth below the board top (mm) and its distance from the hole axis (mm)."""
    columns = ("success", "time_s", "peak_force", "chatter", "protective_stop", "settled",
               "unstable", "steps")  # fmt: skip
    depth = (HOLE_DEPTH - result.final_tip_pos[:, 2]) * 1000
    off_axis = np.linalg.norm(result.final_tip_pos[:, :2] - specs.board_pos, axis=1) * 1000
    rows = [",".join(("trial",) + columns + ("tip_depth_mm", "tip_off_axis_mm"))]
    indices = range(len(result)) if indices is None else indices
    for k, index in enumerate(indices):
        values = [getattr(result, c)[k] for c in columns] + [depth[k], off_axis[k]]
        rows.append(",".join([str(index)] + [f"{float(v):.6g}" for v in values]))
    with open(path, "w") as f:
        f.write("\n".join(rows) + "\n")


def changed(vector: np.ndarray, text: str) -> np.ndarray:
    """`vector` with the changes 'NAME*=F;NAME+=V;NAME-=V' to numbers named as in PARAM_NAMES."""
    out = np.array(vector, dtype=np.float64)
    for item in filter(None, (t.strip() for t in text.split(";"))):
        match = re.fullmatch(r"(.+?)\s*([*+-])=\s*(\S+)", item)
        if match is None or match[1] not in PARAM_NAMES:
            raise SystemExit(f"--change: cannot read {item!r} (NAME*=F, NAME+=V or NAME-=V)")
        k, value = PARAM_NAMES.index(match[1]), float(match[3])
        out[k] = {"*": out[k] * value, "+": out[k] + value, "-": out[k] - value}[match[2]]
    return out


def search_changes(changes: str) -> dict[str, float | str]:
    """{NAME: V} of 'NAME=V;...' (SkillConfig constants, each read as --skill-constant reads
    it: a number, or a name for those that are names)."""
    return dict(skill_constant(item) for item in changes.split(";") if item)


def search_config(skill, changes: str):
    """The SkillConfig of `skill` (an ablation's name, experiments/ablations.py, or a
    SkillConfig) with the constants of 'NAME=V;...' changed."""
    search = ablation(skill) if isinstance(skill, str) else skill
    return search.replace(**search_changes(changes))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=500)
    p.add_argument("--time-limit", type=float, default=60.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--first", action="store_true", help="the first hand-tuned baseline")
    p.add_argument("--full-time-limit", action="store_true", help="run every failure to the limit")
    p.add_argument("--threads", type=int, default=None, help="lanes (default: every core)")
    p.add_argument("--processes", type=int, default=None, help="lanes in worker processes")
    p.add_argument("--pass", dest="control_pass", choices=("numpy", "compiled"), default=None,
                   help="the control period's pass (default: the engine's)")  # fmt: skip
    p.add_argument("--policy", default="baseline", help="'baseline' or a training run directory")
    p.add_argument("--sensor", default="nominal", choices=SENSOR_VARIANTS)
    p.add_argument("--friction", type=float, help="every trial's friction (default: drawn)")
    p.add_argument("--csv", help="write one row per trial here")
    p.add_argument("--indices", help="a file of trial indices (one per line): only those trials")
    p.add_argument("--shapes", default="circle,square", help="comma-separated")
    p.add_argument("--size-mm", type=float, default=50.0, help="the pegs' size S (mm)")
    p.add_argument("--linear-mm", type=float, default=4.0, help="localization error range, +-mm")
    p.add_argument("--angular-deg", type=float, default=6.0, help="grasp tilt range, +-deg")
    p.add_argument(
        "--grasp-model",
        default="board",
        choices=GRASP_MODELS,
        help="where the grasp errors go (flange: the peg tilted in the gripper, the model before "
        "the board's)",
    )
    p.add_argument(
        "--change",
        default="",
        help="a variant of the baseline: 'NAME*=F;NAME+=V;NAME-=V' with names of "
        "skill.params.PARAM_NAMES, e.g. 'C[0,0]*=0.3;C[1,1]*=0.3'",
    )
    p.add_argument(
        "--deadband",
        default="0,0",
        help="force (N), moment (N m) dead bands of the "
        "wrench the compliance acts on (TrialConfig.force_deadband, moment_deadband)",
    )
    add_skill_option(p)
    p.add_argument(
        "--search",
        default="",
        help="the search's constants changed, 'NAME=V;...' with names of skill.search.SkillConfig,"
        " e.g. 'press_accel=2;centre_gain=0'",
    )
    args = p.parse_args(argv)
    policy = args.policy if args.policy == "baseline" else load_policy(args.policy)
    skill = chosen(args.skill, policy)
    args.skill = skill.name
    search = search_config(skill.config, args.search)
    task = TaskConfig(shapes=tuple(args.shapes.split(",")), sizes=(args.size_mm / 1000,),
                      linear_error=args.linear_mm / 1000,
                      angular_error=math.radians(args.angular_deg),
                      grasp_model=args.grasp_model)  # fmt: skip
    force_deadband, moment_deadband = (float(v) for v in args.deadband.split(","))
    specs = sample_trials(task, args.seed, args.trials)
    indices = None
    if args.indices:
        indices = np.loadtxt(args.indices, dtype=np.int64, ndmin=1)
        if indices.size == 0 or indices.min() < 0 or indices.max() >= args.trials:
            raise SystemExit(f"--indices: indices in 0..{args.trials - 1}, one per line")
        specs = specs.take(indices)
    if args.friction is not None:  # the same trials, one friction
        specs = dataclasses.replace(specs, friction=np.full(len(specs), args.friction))
    if args.policy != "baseline":
        vec = policy.controller_vectors(specs)
        label = f"policy {args.policy}"
    else:
        vec = changed(first_baseline() if args.first else baseline_params(), args.change)
        label = f"{'first' if args.first else 'current'} baseline"
    start = time.perf_counter()
    config = TrialConfig(
        time_limit_s=args.time_limit,
        end_settled=not args.full_time_limit,
        sensor=sensor_variant(args.sensor),
        force_deadband=force_deadband,
        moment_deadband=moment_deadband,
        search=search,
    )
    compiled = None if args.control_pass is None else args.control_pass == "compiled"
    result = run_trials(specs, vec, engine="mujoco", config=config, threads=args.threads,
                        processes=args.processes, compiled=compiled)  # fmt: skip
    wall = time.perf_counter() - start
    steps = int(result.steps.sum())
    times = result.time_s[result.success]
    p10, p50, p90 = np.percentile(times, [10, 50, 90]) if times.size else (np.nan,) * 3
    print(
        f"{label}, skill {args.skill} {search}, sensor {args.sensor}, "
        f"{'friction ' + format(args.friction, 'g') + ', ' if args.friction is not None else ''}"
        f"{args.shapes} {args.size_mm:g} mm, +-{args.linear_mm:g} mm / +-{args.angular_deg:g} deg, "
        f"{len(specs)} trials{' of ' + str(args.trials) if indices is not None else ''}, seed "
        f"{args.seed}, {args.time_limit:g} s"
        f"{', every failure to the limit' if args.full_time_limit else ''}: {result.summary()}"
    )
    print(f"time to insert p10 / p50 / p90: {p10:.2f} / {p50:.2f} / {p90:.2f} s; wall {wall:.0f} s "
          f"for {steps:,} physics steps ({steps / wall:,.0f} steps/s)")  # fmt: skip
    rows = taxonomy.table(specs, result.to_arrays(), config.time_limit_s, config.timestep)
    print(taxonomy.markdown(rows, len(specs)), end="")
    if args.csv:
        write_csv(args.csv, result, specs, indices)


if __name__ == "__main__":
    main()
