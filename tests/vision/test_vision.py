"""Vision: labels against the rendered geometry, seeds, the NumPy export, a tiny trained
localizer, the CLI's one-line errors. Small renders (320 x 240) and tiny networks."""

from __future__ import annotations

import json
import math

import mujoco
import numpy as np
import pytest

from mjx_peg.vision import cli, dataset, forward
from mjx_peg.vision.camera import CalibrationError, CameraCalibration
from mjx_peg.vision.figures import hole_outline
from mjx_peg.vision.views import ViewConfig
from mjx_peg.world import constants

PIXEL_TOL = 1.0  # px: a label's projected hole centre vs the rendered marker
FORWARD_TOL = 1e-4  # NumPy export vs Flax, float32
SMALL = dict(width=320, height=240, shapes=("square",), sizes_mm=(50.0,))


def _marker_render(board: dict, view: dict, width: int, height: int) -> np.ndarray:
    """Raw render with the `hole` site as a green sphere at the board-top hole centre."""
    with dataset.Renderer(width, height) as renderer:
        model, data, ren = renderer._scene(board["shape"], board["size"])
        dataset.apply_view(model, data, board, view)
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "hole")
        model.site_pos[site] = (0.0, 0.0, constants.HOLE_DEPTH)
        model.site_sameframe[site] = 0  # the compiler marked it "at the body origin"
        model.site_size[site] = 0.008
        model.site_rgba[site] = (0.0, 1.0, 0.0, 1.0)
        mujoco.mj_forward(model, data)
        option = mujoco.MjvOption()
        option.sitegroup[4] = 1
        ren.update_scene(data, camera="birdseye", scene_option=option)
        return np.array(ren.render(), dtype=np.int32)


@pytest.mark.parametrize(("shape", "seed"), [("square", 3), ("triangle", 4)])
def test_label_is_the_rendered_hole_centre(shape, seed):
    config = dataset.SplitConfig(count=1, seed=seed, width=640, height=480, shapes=(shape,))
    board, view = dataset.draw(config, 0)
    view["distractors"] = []
    view["lights"].update(head_ambient=0.6, head_diffuse=0.6, key_shadow=False)
    view["board_look"]["rgb"] = [0.2, 0.2, 0.8]
    view["table"].update(rgb=[0.9, 0.3, 0.3], texture="plain")
    img = _marker_render(board, view, 640, 480)
    green = (img[..., 1] > 200) & (img[..., 0] < 80) & (img[..., 2] < 80)
    v, u = np.nonzero(green)
    assert u.size > 10, "the marker is not visible"
    label = dataset.make_label(board, view)
    assert np.hypot(u.mean() - label["hole_px"][0], v.mean() - label["hole_px"][1]) < PIXEL_TOL
    # The calibration a user has is within the stated error of the true camera.
    calib = CameraCalibration.from_json(label["calibration"])
    true = CameraCalibration.from_json(view["camera_true"])
    assert np.abs(calib.t_base_camera - true.t_base_camera).max() <= 0.001 + 1e-12
    top = np.array([board["x"], board["y"], constants.HOLE_DEPTH])
    back = calib.unproject_to_plane(true.project(top), constants.HOLE_DEPTH)
    assert np.hypot(*(back - top)[:2]) < 0.004  # 1 mm + 0.05 deg about each axis


def test_calibration_round_trip_and_distortion():
    calib = CameraCalibration.from_mujoco(
        (0.35, 0.0, 1.3),
        np.diag([1.0, 1.0, 1.0]) @ np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1.0]]).T,
        45.0,
        1280,
        960,
    )
    again = CameraCalibration.from_json(json.loads(json.dumps(calib.to_json())))
    points = np.array([[0.5, 0.2, 0.08], [0.3, -0.4, 0.0]])
    np.testing.assert_allclose(again.project(points), calib.project(points), atol=1e-9)
    np.testing.assert_allclose(
        calib.unproject_to_plane(calib.project(points), 0.08)[0], points[0], atol=1e-9
    )
    doc = calib.to_json() | {"distortion": [-0.1, 0.02, 1e-3, -1e-3, 0.0]}
    bent = CameraCalibration.from_json(doc)
    uv = bent.project(points)
    assert np.abs(uv - calib.project(points)).max() > 1.0
    np.testing.assert_allclose(bent.unproject_to_plane(uv[1], 0.0), points[1], atol=1e-7)


def test_renders_are_deterministic_by_seed(tmp_path):
    config = dataset.SplitConfig(count=2, seed=5, **SMALL)
    assert dataset.draw(config, 1) == dataset.draw(config, 1)
    dataset.render_split(tmp_path / "a", config, progress=False)
    dataset.render_split(tmp_path / "b", config, progress=False)
    for name in ("000000.png", "000001.png", "000001.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    (tmp_path / "a" / "000001.json").unlink()  # resume: only the missing image is redone
    assert dataset.render_split(tmp_path / "a", config, progress=False) == 1
    assert (tmp_path / "a" / "000001.png").read_bytes() == (
        tmp_path / "b" / "000001.png"
    ).read_bytes()
    other = dataset.SplitConfig(count=1, seed=6, **SMALL)
    assert dataset.draw(other, 0) != dataset.draw(config, 0)


@pytest.mark.parametrize("shape", ["square", "triangle"])
def test_mirrored_yaw_encoding_matches_mirrored_outline(shape):
    from mjx_peg.vision.training import mirror_encoding

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


def test_numpy_forward_matches_flax():
    from mjx_peg.vision.nets import build, flat_params
    from mjx_peg.vision.training import init_params

    arch = {
        "detector": {"convs": [[4, 2], [6, 1], [8, 2]]},
        "regressor": {"convs": [[4, 2], [6, 2]], "dense": [8]},
    }
    det, reg = build(arch)
    rng = np.random.default_rng(1)
    xd = rng.normal(size=(2, 32, 24, 3)).astype(np.float32)
    xr = rng.normal(size=(2, 16, 16, 3)).astype(np.float32)
    pd = {"params": init_params(det, xd.shape, rng)}
    pr = {"params": init_params(reg, xr.shape, rng)}
    params = {**flat_params("detector", pd), **flat_params("regressor", pr)}
    np.testing.assert_allclose(
        forward.detector_forward(arch["detector"], params, xd), det.apply(pd, xd), atol=FORWARD_TOL
    )
    np.testing.assert_allclose(
        forward.regressor_forward(arch["regressor"], params, xr),
        reg.apply(pr, xr),
        atol=FORWARD_TOL,
    )


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


def _one_line_error(capsys, argv) -> str:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_bad_input_is_one_line(tmp_path, capsys):
    calib = CameraCalibration.from_mujoco((0.35, 0, 1.3), np.eye(3), 45.0, 64, 48)
    good = calib.save(tmp_path / "camera.json")
    err = _one_line_error(
        capsys, ["localize", str(tmp_path / "missing.png"), "--camera", str(good)]
    )
    assert "does not exist" in err
    from PIL import Image

    Image.fromarray(np.zeros((48, 64, 3), np.uint8)).save(tmp_path / "img.png")
    doc = calib.to_json()
    del doc["intrinsics"]
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    err = _one_line_error(
        capsys, ["localize", str(tmp_path / "img.png"), "--camera", str(tmp_path / "bad.json")]
    )
    assert "intrinsics" in err
    err = _one_line_error(
        capsys,
        [
            "localize",
            str(tmp_path / "img.png"),
            "--camera",
            str(good),
            "--model",
            str(tmp_path / "nomodel"),
        ],
    )
    assert "train one first" in err
    _one_line_error(
        capsys, ["render", "--out", str(tmp_path / "r"), "--count", "2", "--condition", "foggy"]
    )
    err = _one_line_error(
        capsys,
        [
            "evaluate",
            "--model",
            str(tmp_path / "m"),
            "--data",
            str(tmp_path / "d"),
            "--out",
            str(tmp_path / "m" / "eval"),
        ],
    )
    assert "an output never replaces an input" in err
    _one_line_error(capsys, ["act", "--out", str(tmp_path / "a"), "--trials", "0"])
    with pytest.raises(CalibrationError):
        CameraCalibration.from_json(doc | {"intrinsics": {"fx": 1, "fy": 1, "cx": 0}})


def test_reading_commands_default_to_the_shipped_localizer():
    """evaluate, localize, act and figures read policies/localizer without --model (and it loads);
    train writes a new one to runs/vision/model."""
    from pathlib import Path

    from mjx_peg.policy.shipped import SHIPPED_DIR
    from mjx_peg.vision.localizer import Localizer

    parser = cli.build_parser()
    for argv in (
        ["evaluate", "--data", "d", "--out", "o"],
        ["localize", "img.png", "--camera", "c.json"],
        ["act", "--out", "o"],
        ["figures", "--data", "d"],
    ):
        assert parser.parse_args(argv).model == SHIPPED_DIR / "localizer"
    assert parser.parse_args(["train", "--data", "d"]).out == Path("runs/vision/model")
    assert Localizer.load(SHIPPED_DIR / "localizer") is not None


@pytest.mark.parametrize("skill", [None, "spiral"])
def test_act_runs_the_named_skill(tmp_path, monkeypatch, skill):
    """`act --skill NAME` runs that skill; without it, the policy's own (run_act's None)."""
    from mjx_peg.vision import act, localizer

    seen = {}

    def fake_run_act(loc, policy, out, *args, skill=None, **kwargs):
        seen["skill"] = skill
        return {"all": dict.fromkeys(("vision_success", "sampled_success", "exact_success"), 1)}

    monkeypatch.setattr(act, "run_act", fake_run_act)
    monkeypatch.setattr(localizer.Localizer, "load", staticmethod(lambda path: None))
    argv = ["act", "--out", str(tmp_path / "a"), "--trials", "1", "--no-progress"]
    assert cli.main(argv + (["--skill", skill] if skill else [])) == 0
    assert seen == {"skill": skill}


def test_act_records_the_skill_it_ran(tmp_path):
    """summary.json records the skill's name and every constant: without a skill, the one the
    policy's manifest names (the shipped `paper`: spiral)."""
    import json

    from mjx_peg.policy.shipped import SHIPPED_DIR
    from mjx_peg.skill.search import SKILLS, constants_record
    from mjx_peg.vision import act
    from mjx_peg.vision.localizer import Localizer

    loc = Localizer.load(SHIPPED_DIR / "localizer")
    act.run_act(loc, "paper", tmp_path, shapes=("circle",), trials=1, time_limit_s=0.1,
                progress=False)  # fmt: skip
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["skill"] == "spiral"
    assert summary["skill_constants"] == constants_record(SKILLS["spiral"])


def test_inference_needs_neither_jax_nor_mujoco():
    """The robot's computer can localize: the localizer and the CLI's parser import NumPy only."""
    import subprocess
    import sys

    code = (
        "import sys, mjx_peg.vision.localizer, mjx_peg.vision.cli; "
        "bad = [m for m in sys.modules if m.split('.')[0] in ('jax', 'flax', 'mujoco', 'optax')]; "
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
