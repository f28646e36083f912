"""The replayed failure of docs/design/credible_contact.md: a trial found again, rerun and plotted.

    python experiments/replay_failure.py --policy runs/paper_cc --old-policy runs/paper_before_cc \
        --out docs/replay_failure.png

The trial: the first failure of range 7 (circle, +-0.32 mm / +-6.9 deg) of the `paper` grid
(seed 0) of `--old-policy` under the trial before credible contact (an ideal F/T sensor, no
compliance damping, no protective stop, the 1 s approach), searched at 5 s per trial and
confirmed at 60 s. That trial is then run under the current trial with `--policy` (plotted to
`--out` as `mjx-peg-demo` plots a trial) and with the baseline. `--trials` and the time limits
shrink the run (for tests).
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.evaluation import config as grid
from mjx_peg.evaluation import demo
from mjx_peg.evaluation.runner import load_controller
from mjx_peg.skill import dmp, sensor

RANGE = 7


def old_trial(time_limit_s: float) -> TrialConfig:
    """The trial before credible contact."""
    ideal = sensor.SensorConfig(cutoff_hz=np.inf, delay_steps=0, force_noise=0.0,
                                torque_noise=0.0, force_bias=0.0, torque_bias=0.0)  # fmt: skip
    return TrialConfig(
        time_limit_s=time_limit_s, sensor=ideal, coupling_time_constant=0.0, max_tool_force=1e9,
        dmp=dmp.DMPConfig(duration=1.0), end_settled=False,
    )  # fmt: skip


def paper_grid() -> grid.EvalConfig:
    """The nominal `paper` grid as `eval.py --grid paper` runs it (circle and square, 50 mm)."""
    linear, angular, trials = grid.grid_axes("paper", grid.PRESET_SIZE_MM)
    return grid.EvalConfig(policy="baseline", grid="paper", linear_mm=linear, angular_deg=angular,
                           trials=trials, shapes=grid.DEFAULT_SHAPES,
                           size_mm=grid.PRESET_SIZE_MM)  # fmt: skip


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", required=True, help="the retrained policy's run directory")
    p.add_argument("--old-policy", required=True, help="the policy trained before credible contact")
    p.add_argument("--out", type=pathlib.Path, required=True, help="the figure (PNG)")
    p.add_argument("--trials", type=int, help="search the range's first N trials (default: all)")
    p.add_argument("--search-time-limit", type=float, default=5.0, help="s, old trial")
    p.add_argument("--confirm-time-limit", type=float, default=60.0, help="s, old trial")
    p.add_argument("--time-limit", type=float, default=60.0, help="s, the current trial")
    args = p.parse_args(argv)
    config = paper_grid()
    specs = grid.range_specs(config, RANGE)
    if args.trials is not None:
        specs = specs.take(np.arange(args.trials))
    lin, ang = config.ranges[RANGE]
    _, old_controller = load_controller(args.old_policy)
    search = old_trial(args.search_time_limit)
    old = run_trials(specs, old_controller(specs), engine="mujoco", config=search)
    failed = np.flatnonzero(~old.success)
    if failed.size == 0:
        raise SystemExit(f"replay_failure.py: no failure among {len(specs)} trials")
    index = int(failed[0])
    one = specs.take([index])
    confirm = old_trial(args.confirm_time_limit)
    confirmed = run_trials(one, old_controller(one), engine="mujoco", config=confirm)
    print(f"range {RANGE} (±{lin:g} mm / ±{ang:g} deg), {len(specs)} trials: first failure of "
          f"{args.old_policy} under the old trial ({args.search_time_limit:g} s) is trial "
          f"{index}; at {args.confirm_time_limit:g} s: {confirmed.summary()}")  # fmt: skip
    now = TrialConfig(time_limit_s=args.time_limit)
    _, controller = load_controller(args.policy)
    run = demo.run_demo(one, controller(one), now, frames=0)  # its result and its trace
    print(f"under the current trial, {args.policy}: {run['result'].summary()}")
    _, baseline = load_controller("baseline")
    result = run_trials(one, baseline(one), engine="mujoco", config=now)
    print(f"under the current trial, baseline: {result.summary()}")
    demo.plot_trial(run, args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
