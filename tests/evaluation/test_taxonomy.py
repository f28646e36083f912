"""The failure taxonomy: each class from a tip placed where that failure ends."""

import math

import numpy as np

from mjx_peg.evaluation import taxonomy
from mjx_peg.world.constants import HOLE_DEPTH
from mjx_peg.world.task import TaskConfig, hole_frame, sample_trials


def test_each_failure_lands_in_its_class_on_a_tilted_board():
    specs = sample_trials(TaskConfig(shapes=("square",), angular_error=math.radians(8.0)), 2, 8)
    origin, axis = hole_frame(specs)
    side = np.cross(axis, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side, axis=1, keepdims=True)  # a direction in the board's top plane
    entrance = origin + HOLE_DEPTH * axis
    # (depth below the entrance, distance from the axis) of each trial's tip, in m
    where = [(0.07, 0.0), (0.03, 0.001), (0.0, 0.03), (0.0, 0.08), (-0.02, 0.0), (0.0, 0.0),
             (0.0, 0.03), (0.0, 0.03)]  # fmt: skip
    tips = np.stack([entrance[i] - d * axis[i] + r * side[i] for i, (d, r) in enumerate(where)])
    arrays = dict(
        final_tip_pos=tips,
        success=np.array([True] + [False] * 7),
        unstable=np.array([False] * 6 + [True, False]),
        protective_stop=np.array([False] * 7 + [True]),
        settled=np.array([False, False, True, True, True, False, False, False]),
        steps=np.array([500, 1000, 700, 700, 700, 1000, 30, 30]),
    )
    depth, lateral = taxonomy.tip_at_hole(specs, tips)
    np.testing.assert_allclose(depth, [d for d, _ in where], atol=1e-12)
    np.testing.assert_allclose(lateral, [r for _, r in where], atol=1e-12)
    label = taxonomy.classify(specs, arrays)
    names = [taxonomy.CLASSES[k] if k >= 0 else "success" for k in label]
    assert names == ["success", "wedged in the hole", "on the rim", "crept away", "above the board",
                     "on the rim", "unstable", "protective stop"]  # fmt: skip
    rows = taxonomy.table(specs, arrays, time_limit_s=2.0, timestep=0.002)
    by = {r["failure"]: r for r in rows}
    assert by["on the rim"]["trials"] == 2 and by["on the rim"]["still_moving"] == 1
    assert by["wedged in the hole"]["still_moving"] == 1
    assert abs(by["crept away"]["lateral_mm"] - 80.0) < 1e-9
    text = taxonomy.markdown(rows, len(specs))
    assert text.startswith("7 of 8 trials failed") and "| on the rim | 2 | 25.0 | 1 |" in text
