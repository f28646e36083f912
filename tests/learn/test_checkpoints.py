"""learn/checkpoints.py: Orbax checkpoints round-trip into a template; another state is one line."""

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.learn.checkpoints import Checkpoints, has_steps


def test_checkpoints_round_trip_into_the_template(tmp_path):
    tree = {"w": np.arange(6, dtype=np.float32).reshape(2, 3), "step": np.asarray(5, np.int64)}
    tree["opt"] = (np.ones(2), {"mu": np.zeros((2, 3), np.float32)})
    template = {
        "w": np.zeros((2, 3), np.float32),
        "step": np.zeros((), np.int64),
        "opt": (np.zeros(2), {"mu": np.ones((2, 3), np.float32)}),
    }
    where = tmp_path / "checkpoints"
    assert not has_steps(where) and not where.exists()
    with Checkpoints(where, keep=2) as saved:
        assert saved.latest_step() is None
        for step in (1, 2, 3):
            saved.save(step, {**tree, "step": np.asarray(step, np.int64)})
        assert saved.latest_step() == 3
        back = saved.restore(template)
        first_kept = saved.restore(template, step=2)
    assert has_steps(where) and sorted(p.name for p in where.iterdir() if p.is_dir()) == ["2", "3"]
    assert int(back["step"]) == 3 and int(first_kept["step"]) == 2
    np.testing.assert_array_equal(back["w"], tree["w"])
    np.testing.assert_array_equal(back["opt"][1]["mu"], tree["opt"][1]["mu"])
    assert back["w"].dtype == np.float32 and isinstance(back["opt"], tuple)

    with Checkpoints(where, keep=2) as saved, pytest.raises(UsageError) as caught:
        saved.restore({**template, "extra": np.zeros(1)})  # another state than was saved
    assert f"checkpoint {where.absolute() / '3'} is corrupt or truncated" in str(caught.value)
    assert "\n" not in str(caught.value)
