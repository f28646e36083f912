"""The engine tests' trials: every shape at two sizes, errors large enough that some fail."""

import numpy as np
import pytest

from mjx_peg.world.task import TaskConfig, sample_trials


def _mixed_specs(n: int, seed: int):
    config = TaskConfig(
        shapes=("circle", "square", "triangle"),
        sizes=(0.05, 0.06),
        linear_error=0.004,
        angular_error=np.deg2rad(6.0),
    )
    return sample_trials(config, seed, n)


@pytest.fixture
def mixed_specs():
    """(n, seed) -> n trials of every shape at 50 and 60 mm, +-4 mm / +-6 deg."""
    return _mixed_specs
