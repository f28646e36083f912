"""The README's replayed failure, found again and rerun under the credible trial (issue 18).

    python benchmarks/replay_failure.py --policy runs/paper_cc --old-policy runs/paper_before_cc \
        --out docs/replay_failure.png

Before credible contact the README replayed `mjx-peg-demo --replay runs/eval/nominal --range 7
--trial failure`: the first failure of range 7 (circle, +-0.32 mm / +-6.9 deg) of the nominal
`paper` grid (seed 0) of the policy then trained (`--old-policy`). That evaluation's per-trial
files were not kept, so the trial is found again: range 7's 200 specs (they depend only on the
grid and its seed) run with the old policy under the old trial (an ideal F/T sensor, no
compliance damping, no protective stop, the 1 s approach), 5 s each (its successes took under
4.1 s), and the first one that fails is run to 60 s to confirm it (a failure, chattering). That
same spec is then run under the current trial with `--policy` (and with the baseline), and the
`--policy` run is plotted as `mjx-peg-demo` plots a trial.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.evaluation import demo, eval_cli
from mjx_peg.evaluation import grid as evaluation
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


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", required=True, help="the retrained policy's run directory")
    p.add_argument("--old-policy", required=True, help="the policy trained before issue 18")
    p.add_argument("--out", type=pathlib.Path, required=True, help="the figure (PNG)")
    args = p.parse_args()
    nominal = eval_cli.build_parser().parse_args(
        ["--policy", "baseline", "--grid", "paper", "--out", "unused"]
    )
    config = eval_cli.config_from_args(nominal, "baseline")
    specs = evaluation.range_specs(config, RANGE)
    lin, ang = config.ranges[RANGE]
    _, old_controller = evaluation.load_controller(args.old_policy)
    old = run_trials(specs, old_controller(specs), engine="mujoco", config=old_trial(5.0))
    index = int(np.flatnonzero(~old.success)[0])
    one = specs.take([index])
    confirm = run_trials(one, old_controller(one), engine="mujoco", config=old_trial(60.0))
    print(f"range {RANGE} (±{lin:g} mm / ±{ang:g} deg), {len(specs)} trials: first failure of "
          f"{args.old_policy} under the old trial (5 s) is trial {index}; at 60 s: "
          f"{confirm.summary()}")  # fmt: skip
    now = TrialConfig()
    _, controller = evaluation.load_controller(args.policy)
    run = demo.run_demo(one, controller(one), now, frames=0)  # its result and its trace
    print(f"under the current trial, {args.policy}: {run['result'].summary()}")
    _, baseline = evaluation.load_controller("baseline")
    result = run_trials(one, baseline(one), engine="mujoco", config=now)
    print(f"under the current trial, baseline: {result.summary()}")
    demo.plot_trial(run, args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
