"""engines/trial.py: the settle test ends a trial at rest or repeating one oscillation, only."""

import numpy as np
import pytest

from mjx_peg.engines.trial import TrialConfig


def test_settle_update_ends_rest_and_repeating_oscillations_only():
    """At rest or repeating the same oscillation after settle_after_s: settled one window after
    the first window that matches its predecessor; drifting or before settle_after_s: never."""
    from mjx_peg.engines.trial import is_settled, settle_start, settle_update

    config = TrialConfig(settle_after_s=1.0, settle_window_s=0.5)
    dt = config.timestep
    steps = np.arange(int(6.0 / dt))
    t = steps * dt
    chatter = np.where(steps % 2 == 0, 50.0, -50.0)  # a 250 Hz force oscillation
    cases = {
        "rest": (np.zeros_like(t), np.zeros_like(t), 2.0),
        "chatter": (np.zeros_like(t), chatter, 2.0),
        # settles only once it stops moving at 3 s: windows [3, 3.5) and [3.5, 4) match
        "stops at 3 s": (1e-3 * np.minimum(t, 3.0), np.zeros_like(t), 4.0),
        "creeps": (2e-4 * t, np.zeros_like(t), None),  # 0.2 mm/s: 0.1 mm per window
        "chatter grows": (np.zeros_like(t), chatter * (1 + t), None),
    }
    for name, (tip_z, force, expected) in cases.items():
        state, settled_at = settle_start(), None
        for k in steps:
            tip = np.array([0.4, 0.1, 0.08 + tip_z[k]])
            wrench = np.array([0.0, 0.0, force[k], 0.0, 0.0, 0.0])
            state = settle_update(state, k, np.zeros(6), tip, wrench, config)
            if settled_at is None and is_settled(state, config):
                settled_at = (k + 1) * dt
        if expected is None:
            assert settled_at is None, name
        else:
            assert settled_at == pytest.approx(expected), name
    assert not is_settled(state._replace(matched=5), config.replace(end_settled=False))


def test_chatter_counts_past_the_approach_and_chatters_from_its_limit():
    """One reading of the chatter metric for every table: a trial's chatter counts only past 1.2
    s (a protective stop at 1.128 s, as a touchdown's, holds the approach in its window), and a
    counted trial chatters at 5 N or more."""
    from mjx_peg.engines.trial import chatter_counted, chattering

    time_s = np.array([1.128, 1.2, 1.21, 60.0, 60.0])
    chatter = np.array([9.0, 9.0, 5.0, 4.99, 5.5])
    assert chatter_counted(time_s).tolist() == [False, False, True, True, True]
    assert chattering(chatter, time_s).tolist() == [False, False, True, False, True]
