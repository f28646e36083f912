"""The vision side of the family of parts: every part renders with an exact label, and the
shipped localizer says in one line which parts it cannot localize rather than guess."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.vision import cli, dataset
from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.vision.figures import hole_outline
from mjx_peg.vision.localizer import Localizer
from mjx_peg.world import constants, parts


def _one_line(capsys, argv) -> str:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("shape", ["hexagon", "rectangle"])
def test_new_parts_render_with_their_hole_and_labels_without_a_class(shape):
    """A new part at a size the localizer never learned, right under the camera: through its
    hole's outline (drawn through the true camera) the table shows within, the board without;
    its label has no shape or size class for the localizer to learn."""
    config = dataset.SplitConfig(count=1, seed=3, width=640, height=480, shapes=(shape,),
                                 sizes_mm=(80.0,))  # fmt: skip
    board, view = dataset.draw(config, 0)
    board.update(x=0.35, y=0.0)  # under the bird's-eye camera: the walls seen edge-on
    view["distractors"] = []
    view["board_look"].update(rgb=[0.1, 0.1, 0.9], texture="plain")
    view["table"].update(rgb=[0.9, 0.1, 0.1], texture="plain")
    with dataset.Renderer(640, 480) as renderer:
        image = renderer.raw(board, view).astype(float)
    label = dataset.make_label(board, view)
    assert (label["board"]["shape"], label["board"]["size"]) == (shape, 0.08)
    assert label["shape_class"] is None and label["size_class"] is None
    true = CameraCalibration.from_json(view["camera_true"])
    centre = np.array([board["x"], board["y"], constants.HOLE_DEPTH])
    outline = hole_outline(shape, board["size"], board["x"], board["y"], board["yaw"])[:-1]
    for scale, table in ((0.85, True), (1.15, False)):
        for u, v in true.project(centre + scale * (outline - centre)):
            red, _, blue = image[int(round(v)), int(round(u))]
            assert (red > blue) == table, (scale, u, v)
    with pytest.raises(UsageError, match=f"--data renders {shape}, 80 mm: the localizer learns"):
        dataset.check_trainable(config, "--data")


def test_splits_take_every_shape_and_sizes_10_to_80_mm():
    dataset.SplitConfig(count=1, seed=0, shapes=constants.SHAPES, sizes_mm=(10.0, 80.0))
    with pytest.raises(UsageError, match=r"sizes must lie in \[10, 80\] mm"):
        dataset.SplitConfig(count=1, seed=0, sizes_mm=(90.0,))
    with pytest.raises(UsageError, match="shapes must be some of"):
        dataset.SplitConfig(count=1, seed=0, shapes=("octagon",))
    assert dataset.SplitConfig(count=1, seed=0).shapes == constants.PAPER_SHAPES


@pytest.mark.parametrize("shape", constants.SHAPES)
def test_the_drawn_outline_is_the_part_hole(shape):
    corners = parts.hole_corners(shape, 0.04, 1.02)
    outline = hole_outline(shape, 0.04, 0.5, -0.1, 0.0, 1.02)
    np.testing.assert_allclose(outline[:-1, :2], corners + np.array([0.5, -0.1]), atol=1e-15)
    np.testing.assert_allclose(outline[-1], outline[0])


def test_the_shipped_localizer_refuses_the_parts_it_cannot_localize(tmp_path, capsys):
    """It names and reads the yaw of the paper's three shapes only: on 300 renders of hexagon
    and rectangle holes it found the centre (p99 2.9 / 6.3 mm) but called every hexagon a
    circle and 93 % of rectangles squares, with yaw errors spread over the whole symmetry period;
    so the CLIs refuse those shapes in one line."""
    loc = Localizer.load(cli.SHIPPED_MODEL)
    assert loc.shapes == constants.PAPER_SHAPES
    assert loc.check_shape("triangle") == "triangle"
    for shape in ("hexagon", "rectangle"):
        with pytest.raises(UsageError, match=f"cannot localize {shape} holes"):
            loc.check_shape(shape)
    calib = CameraCalibration.from_mujoco((0.35, 0, 1.3), np.eye(3), 45.0, 64, 48)
    camera = calib.save(tmp_path / "camera.json")
    from PIL import Image

    Image.fromarray(np.zeros((48, 64, 3), np.uint8)).save(tmp_path / "img.png")
    err = _one_line(capsys, ["localize", str(tmp_path / "img.png"), "--camera", str(camera),
                             "--shape", "hexagon"])  # fmt: skip
    assert "--shape hexagon: this localizer cannot localize hexagon holes" in err
    err = _one_line(capsys, ["act", "--out", str(tmp_path / "a"), "--shapes", "circle,rectangle"])
    assert "--shapes rectangle: this localizer cannot localize rectangle holes" in err
    assert not (tmp_path / "a").exists()


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
