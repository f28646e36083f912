"""vision/training.py: the yaw encoding of a mirrored crop is the mirrored hole's; the training
directory is keyed by its config."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.vision.figures import hole_outline
from mjx_peg.vision.training import CONFIG_FILE, VisionTrainConfig, mirror_encoding, prepare_out


@pytest.mark.parametrize("shape", ["square", "triangle"])
def test_mirrored_yaw_encoding_matches_mirrored_outline(shape):
    n = 4 if shape == "square" else 3
    rng = np.random.default_rng(0)
    for yaw in rng.uniform(0, 2 * math.pi, 5):
        enc = np.array(
            [[math.cos(4 * yaw), math.sin(4 * yaw), math.cos(3 * yaw), math.sin(3 * yaw)]]
        )
        outline = hole_outline(shape, 0.05, 0.0, 0.0, yaw)[:-1, :2]
        for fr, fc in ((True, False), (False, True), (True, True)):
            mirrored = outline * np.array([-1.0 if fr else 1.0, -1.0 if fc else 1.0])
            e = mirror_encoding(enc, np.array([fr]), np.array([fc]))[0]
            c, s = (e[0], e[1]) if n == 4 else (e[2], e[3])
            expected = hole_outline(shape, 0.05, 0.0, 0.0, math.atan2(s, c) / n)[:-1, :2]
            dist = np.linalg.norm(mirrored[:, None] - expected[None], axis=-1).min(axis=1)
            assert dist.max() < 1e-9, (shape, yaw, fr, fc)


def test_the_localizer_training_directory_is_keyed_by_its_config(tmp_path):
    out = tmp_path / "model"
    prepare_out(out, VisionTrainConfig())
    recorded = (out / CONFIG_FILE).read_text()
    assert recorded == json.dumps(VisionTrainConfig().to_json(), indent=2) + "\n"
    (out / "metrics.csv").write_text("step\n")
    prepare_out(out, VisionTrainConfig())  # the same: resumed, nothing changed
    assert (out / CONFIG_FILE).read_text() == recorded and (out / "metrics.csv").is_file()
    other = VisionTrainConfig(seed=3)
    with pytest.raises(UsageError, match="holds a localizer with a different config .seed: 0"):
        prepare_out(out, other)
    notes = []
    prepare_out(out, other, force=True, note=notes.append)
    (moved,) = [p for p in tmp_path.iterdir() if p.name.startswith("model.replaced-")]
    assert sorted(p.name for p in moved.iterdir()) == ["metrics.csv", CONFIG_FILE]
    assert json.loads((out / CONFIG_FILE).read_text())["seed"] == 3 and len(notes) == 1
