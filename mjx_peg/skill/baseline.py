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

from mjx_peg.skill.params import ControllerParams, vector_from_controller

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
