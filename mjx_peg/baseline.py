"""The hand-tuned parameter set: the reference a learned policy must beat.

Reasoning (tau = 1 s, so K = omega^2 of the closed loop; wrench referred to the tcp, goal frame
whose z axis points down into the hole):
- k_t = k_theta = 300 (omega = 17 rad/s): the tcp tracks the DMP within a few mm in free space,
  and orientation errors from the grasp are corrected at the same bandwidth.
- Vertical compliance C[2,2] = 1e-3 m/N sets how hard the peg presses: quasi-statically the goal
  backs off until C F equals the remaining distance to the goal (80 mm when resting on the
  board), i.e. ~80 N. Stiffer (1e-4) pressed with hundreds of N and friction pinned the peg.
- Lateral compliance 1e-3 m/N: rim and wall forces of ~5 N move the goal ~5 mm, the size of the
  localization errors to absorb.
- Rotational compliance 0.05 rad/(N m) about x, y: the peg yields to rim moments like a wrist;
  0.01 about z.
- Moment-to-translation coupling C[1,3] = +3e-3, C[0,4] = -3e-3 m/(N m): a peg resting partly on
  the rim is supported on the side away from the hole, so the moment about the tcp points to the
  hole; these entries turn it into a goal shift towards the hole (in the goal frame, whose y and z
  are world -y and -z). With the opposite signs success halves; without them it drops from 80 %
  to 57 % (square + circle, 40 trials, ±3 mm / ±4 deg, 8 s).
"""

from __future__ import annotations

import numpy as np

from mjx_peg.params import ControllerParams, vector_from_controller

K_T = 300.0
K_THETA = 300.0
COMPLIANCE_DIAGONAL = (1e-3, 1e-3, 1e-3, 0.05, 0.05, 0.01)
MOMENT_TO_SHIFT = 3e-3  # m/(N m)


def baseline_controller() -> ControllerParams:
    """The baseline as ControllerParams (NumPy float64)."""
    compliance = np.diag(np.asarray(COMPLIANCE_DIAGONAL))
    compliance[1, 3] = MOMENT_TO_SHIFT
    compliance[0, 4] = -MOMENT_TO_SHIFT
    return ControllerParams(np.asarray(K_T), np.asarray(K_THETA), compliance)


def baseline_params() -> np.ndarray:
    """(38,) physical parameter vector [k_t, k_theta, C row-major] of the baseline."""
    return np.asarray(vector_from_controller(baseline_controller()), dtype=np.float64)


def main(argv=None) -> int:
    """`python -m mjx_peg.baseline`: success and time of the baseline per shape at given errors."""
    import argparse

    from mjx_peg import scene
    from mjx_peg.engines import ENGINES, run_trials
    from mjx_peg.task import TaskConfig, sample_trials
    from mjx_peg.trial import TrialConfig

    p = argparse.ArgumentParser(prog="python -m mjx_peg.baseline", description=main.__doc__)
    p.add_argument("--shapes", default="circle,square,triangle")
    p.add_argument("--size", type=float, default=50.0, help="characteristic size (mm)")
    p.add_argument("--linear-mm", type=float, default=3.0)
    p.add_argument("--angular-deg", type=float, default=4.0)
    p.add_argument("--trials", type=int, default=100)
    p.add_argument("--time-limit", type=float, default=60.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--engine", default="auto", choices=ENGINES)
    args = p.parse_args(argv)
    shapes = args.shapes.split(",")
    for shape in shapes:
        if shape not in scene.SHAPES:
            p.error(f"unknown shape {shape!r}: choose from {', '.join(scene.SHAPES)}")
    if args.trials <= 0:
        p.error("--trials must be positive")
    try:
        config = TrialConfig(time_limit_s=args.time_limit)
        for shape in shapes:
            task = TaskConfig(
                shapes=(shape,),
                sizes=(args.size / 1000.0,),
                linear_error=args.linear_mm / 1000.0,
                angular_error=np.deg2rad(args.angular_deg),
            )
            specs = sample_trials(task, args.seed, args.trials)
            result = run_trials(specs, baseline_params(), engine=args.engine, config=config)
            print(
                f"{shape} {args.size:g} mm ±{args.linear_mm:g} mm ±{args.angular_deg:g} deg: "
                f"{result.summary()}"
            )
    except ValueError as exc:
        p.error(str(exc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
