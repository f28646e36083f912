"""vision/localizer.py: a tiny localizer, trained on 48 small renders, beats a constant guess."""

from __future__ import annotations

import numpy as np

from mjx_peg.vision import dataset
from mjx_peg.vision.views import ViewConfig

SMALL = dict(width=320, height=240, shapes=("square",), sizes_mm=(50.0,))


def test_tiny_localizer_beats_a_constant_guess(tmp_path):
    from mjx_peg.vision import training
    from mjx_peg.vision.localizer import Localizer
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
