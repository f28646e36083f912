"""The hand-tuned parameter set: the reference a learned policy must beat.

k_t = k_theta = 900 (near the top of the range: the stiff arm yields least to a lateral rim
force); the arm's own cross-compliance at the goal cancelled (C[0,4] = C[4,0] = -6.2/k,
C[1,3] = C[3,1] = +5.7/k: the tip's compliance centred at the tcp, like a remote-centre
compliance); 1.8e-3 m/N along x, y, z (the tip yields to rim and wall forces; C_zz sets the press,
~40 N on the board top); 0.07 rad/(N m) about x, y and 0.01 about z. Every value lies inside its
range and off the sigmoid map's saturated edges (params.py), so a policy started here can move
every number. Why each value, with the measurements behind it: docs/design/baseline_tuning.md.
"""

from __future__ import annotations

import numpy as np

from mjx_peg.skill.params import ControllerParams, vector_from_controller

K_T = 900.0
K_THETA = 900.0
COMPLIANCE_DIAGONAL = (1.8e-3, 1.8e-3, 1.8e-3, 0.07, 0.07, 0.01)
# The arm's own cross-compliance K_y^-1 Lambda^-1 at the goal (goal frame, median over the
# workspace) is +6.2/k at [0,4] and [4,0], -5.7/k at [1,3] and [3,1]; the baseline cancels it.
ARM_TILT_SHIFT_X = 6.2  # (m/(N m)) * (1/s^2): K^-1 Lambda^-1 [0,4] times k
ARM_TILT_SHIFT_Y = -5.7  # [1,3] times k


def baseline_controller() -> ControllerParams:
    """The baseline as ControllerParams (NumPy float64)."""
    compliance = np.diag(np.asarray(COMPLIANCE_DIAGONAL))
    compliance[0, 4] = -ARM_TILT_SHIFT_X / K_T
    compliance[4, 0] = -ARM_TILT_SHIFT_X / K_THETA
    compliance[1, 3] = -ARM_TILT_SHIFT_Y / K_T
    compliance[3, 1] = -ARM_TILT_SHIFT_Y / K_THETA
    return ControllerParams(np.asarray(K_T), np.asarray(K_THETA), compliance)


def baseline_params() -> np.ndarray:
    """(38,) physical parameter vector [k_t, k_theta, C row-major] of the baseline."""
    return np.asarray(vector_from_controller(baseline_controller()), dtype=np.float64)
