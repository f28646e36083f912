"""vision/localizer.py: a tiny localizer, trained on 48 small renders, beats a constant guess;
the shipped one refuses the parts it cannot localize and reads a known shape at its symmetry."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.vision import cli, dataset
from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.vision.localizer import Localizer
from mjx_peg.vision.views import ViewConfig
from mjx_peg.world import constants

SMALL = dict(width=320, height=240, shapes=("square",), sizes_mm=(50.0,))


def test_tiny_localizer_beats_a_constant_guess(tmp_path):
    from mjx_peg.vision import training
    from mjx_peg.vision.metrics import evaluate_items

    dataset.render_split(
        tmp_path / "train", dataset.SplitConfig(count=48, seed=20, **SMALL), progress=False
    )
    dataset.render_split(
        tmp_path / "test", dataset.SplitConfig(count=10, seed=21, **SMALL), progress=False
    )
    arch = {
        "detector": {"convs": [[8, 2], [8, 2], [12, 2], [12, 1]]},
        "regressor": {"convs": [[8, 2], [8, 2], [12, 2], [12, 2]], "dense": [32]},
    }
    config = training.VisionTrainConfig(
        arch=arch,
        crops=2,
        batch=16,
        detector_steps=200,
        regressor_steps=60,
        warmup_steps=10,
        checkpoint_every=1000,
        learning_rate=3e-3,
    )
    views = ViewConfig(
        coarse_rows=64, coarse_cols=112, coarse_res=0.012, fine_size=48, fine_res=0.0025
    )  # coarser than the real ones: the images are 320 x 240
    training.train(tmp_path / "train", tmp_path / "model", config, views=views, progress=False)
    loc = Localizer.load(tmp_path / "model")
    train_xy = np.array(
        [[lb["board"]["x"], lb["board"]["y"]] for _, lb in dataset.split_items(tmp_path / "train")]
    )
    items = dataset.split_items(tmp_path / "test")
    rows = evaluate_items(loc, items, progress=False)
    ours = np.median([r["pos_err_mm"] for r in rows])
    true = np.array([[lb["board"]["x"], lb["board"]["y"]] for _, lb in items])
    constant = np.median(1000 * np.linalg.norm(true - train_xy.mean(axis=0), axis=1))
    assert ours < 0.5 * constant, (ours, constant)


def test_the_shipped_localizer_refuses_the_parts_it_cannot_localize():
    """It names and reads the yaw of the paper's three shapes only: on 300 renders of hexagon
    and rectangle holes it found the centre (p99 2.9 / 6.3 mm) but called every hexagon a
    circle and 93 % of rectangles squares, with yaw errors spread over the whole symmetry period;
    so it refuses those shapes."""
    loc = Localizer.load(cli.SHIPPED_MODEL)
    assert loc.shapes == constants.PAPER_SHAPES
    assert loc.check_shape("triangle") == "triangle"
    for shape in ("hexagon", "rectangle"):
        with pytest.raises(UsageError, match=f"cannot localize {shape} holes"):
            loc.check_shape(shape)


def test_a_known_shape_is_read_at_its_symmetry(tmp_path):
    """`localize(shape=...)`: the part's shape as given, its yaw from that shape's encoding."""
    config = dataset.SplitConfig(count=1, seed=4, shapes=("square",), sizes_mm=(50.0,))
    dataset.render_split(tmp_path, config, progress=False)
    label = json.loads((tmp_path / "000000.json").read_text())
    image = dataset.read_png(tmp_path / "000000.png")
    loc = Localizer.load(cli.SHIPPED_MODEL)
    calib = CameraCalibration.from_json(label["calibration"])
    free, told = loc.localize(image, calib), loc.localize(image, calib, shape="triangle")
    assert free.estimate.shape == "square" and told.estimate.shape == "triangle"
    assert (free.estimate.x, free.estimate.y) == (told.estimate.x, told.estimate.y)
    assert told.to_json()["hole_scale"] == constants.HOLE_SCALE["triangle"]
