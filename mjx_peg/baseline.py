"""The hand-tuned parameter set: the reference a learned policy must beat.

Reasoning (tau = 1 s, so K = omega^2 of the closed loop):
- k_t = 300 /s^2 (omega = 17 rad/s): stiff enough that the tcp tracks the DMP within a few mm in
  free space and pushes with ~300 * dz N/kg-equivalent into contact, soft enough for a 2 ms step.
- k_theta = 300: the same bandwidth for orientation, so tilt from grasp errors is corrected
  while the peg descends.
- Compliance C = K_c^-1, diagonal only (no coupling between axes):
  lateral 4e-4 m/N: a 10 N side force from the hole's wall or chamfer-less rim moves the goal
  4 mm, about the size of the localization errors we expect to absorb;
  vertical 1e-4 m/N: the peg still presses (a jam at 20 N backs the goal off by only 2 mm);
  rotational 0.03 rad/(N m) about x and y: a 1 N m moment from a rim contact tilts the goal
  ~1.7 deg, letting the peg align with the hole; about z 0.01 rad/(N m).
"""

from __future__ import annotations

import numpy as np

from mjx_peg.params import ControllerParams, vector_from_controller

K_T = 300.0
K_THETA = 300.0
COMPLIANCE_DIAGONAL = (4e-4, 4e-4, 1e-4, 0.03, 0.03, 0.01)


def baseline_controller() -> ControllerParams:
    """The baseline as ControllerParams (NumPy float64)."""
    return ControllerParams(
        np.asarray(K_T), np.asarray(K_THETA), np.diag(np.asarray(COMPLIANCE_DIAGONAL))
    )


def baseline_params() -> np.ndarray:
    """(38,) physical parameter vector [k_t, k_theta, C row-major] of the baseline."""
    return np.asarray(vector_from_controller(baseline_controller()), dtype=np.float64)
