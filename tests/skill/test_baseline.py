"""skill/baseline.py: the hand-tuned 38 numbers, inside their ranges, the arm's tilt shift
cancelled."""

import numpy as np

from mjx_peg.skill import params
from mjx_peg.skill.baseline import ARM_TILT_SHIFT_X, ARM_TILT_SHIFT_Y, K_T, baseline_params


def test_the_baseline_vector_is_its_controller():
    vector = baseline_params()
    assert vector.shape == (38,) and vector.dtype == np.float64
    controller = params.controller_from_vector(vector)
    assert float(controller.k_t) == 900.0 and float(controller.k_theta) == 900.0
    c = np.asarray(controller.compliance)
    np.testing.assert_allclose(np.diag(c), [1.8e-3, 1.8e-3, 1.8e-3, 0.07, 0.07, 0.01])
    # the arm's own cross-compliance at the goal, +6.2/k at [0,4], -5.7/k at [1,3], cancelled
    assert c[0, 4] == -ARM_TILT_SHIFT_X / K_T and c[1, 3] == -ARM_TILT_SHIFT_Y / K_T
    off = c.copy()
    off[[0, 4, 1, 3], [4, 0, 3, 1]] = 0.0
    assert not (off - np.diag(np.diag(c))).any()  # no other coupling


def test_the_baseline_is_strictly_inside_the_ranges():
    """A centred map can move every number of it in both directions."""
    np.testing.assert_array_equal(params.check_centre(baseline_params()), baseline_params())
