"""The bird's-eye dataset: randomized renders with exact labels, on disk as PNG + JSON.

    python -m mjx_peg.vision render --out runs/vision/data/train --count 4000 --seed 0

A split directory holds `manifest.json` (how it was made) and, per image k, `NNNNNN.png` (the
camera frame, 8-bit RGB) and `NNNNNN.json` (its label). Image k is drawn from its own generator
`np.random.default_rng([seed, k])`, so a split is the same whether rendered in one go or resumed
(the JSON is written last, atomically: an image without its JSON is rendered again).

Label (JSON, SI units, world = robot base frame):

    board:       shape, size (m), x, y (hole centre on the table, m), yaw (rad, as drawn)
    yaw_mod:     yaw modulo the shape's symmetry, in [0, 2 pi / n) (circle: null)
    size_class, shape_class: indices into the localizer's classes SIZES_MM and SHAPE_CLASSES
                 (null for a size or shape that is none of them)
    hole_px:     (u, v) of the hole centre at the board top (z = HOLE_DEPTH), true camera
    hole_px_table: (u, v) of the hole centre on the table (z = 0), true camera
    calibration: the camera calibration a user would have (camera.py's JSON)
    view:        every random choice (lights, materials, distractors, true camera, sensor)
"""

from __future__ import annotations

import io
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mjx_peg import inputs, outdir
from mjx_peg.errors import UsageError
from mjx_peg.outdir import OutDir, write_json
from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.vision.forward import SHAPE_CLASSES
from mjx_peg.vision.randomize import (
    CONDITIONS,
    SIZES_MM,
    apply_view,
    load_vision_model,
    postprocess,
    sample_board,
    sample_view,
)
from mjx_peg.world import constants

SCHEMA = "mjx-peg-vision-split"


MANIFEST = "manifest.json"
MAX_IMAGE_BYTES = 256 * 2**20  # an image file
MAX_IMAGE_PIXELS = 16_384**2  # width x height


def yaw_period(shape: str) -> float:
    """The shape's rotational symmetry period (rad); inf for the circle."""
    n = constants.SYMMETRY[constants.SHAPES.index(shape)]
    return 2.0 * math.pi / n if n else math.inf


def yaw_mod(shape: str, yaw: float) -> float | None:
    """yaw in [0, period) of the shape's symmetry; None for the circle."""
    period = yaw_period(shape)
    return None if math.isinf(period) else float(np.mod(yaw, period))


class Renderer:
    """Renders boards in the vision scene: one model, data and GL context per (shape, size)."""

    def __init__(self, width: int = 1280, height: int = 960):
        self.width, self.height = int(width), int(height)
        self._scenes: dict = {}

    def scene(self, shape: str, size: float):
        """(model, data, mujoco.Renderer) of the vision scene of (shape, size in m), made on first
        use and kept until `close`; a caller may edit the model (a test marks a site in it)."""
        key = (shape, round(float(size), 6))
        if key not in self._scenes:
            import mujoco

            model = load_vision_model(shape, size)
            model.vis.global_.offwidth = max(self.width, model.vis.global_.offwidth)
            model.vis.global_.offheight = max(self.height, model.vis.global_.offheight)
            data = mujoco.MjData(model)
            self._scenes[key] = (model, data, mujoco.Renderer(model, self.height, self.width))
        return self._scenes[key]

    def raw(self, board: dict, view: dict) -> np.ndarray:
        """(H, W, 3) uint8 rendered frame of `board` under `view`, before the sensor."""
        model, data, renderer = self.scene(board["shape"], board["size"])
        apply_view(model, data, board, view)
        renderer.update_scene(data, camera="birdseye")
        return np.array(renderer.render(), dtype=np.uint8)

    def image(self, board: dict, view: dict) -> np.ndarray:
        """(H, W, 3) uint8 camera image: the frame through the sensor model."""
        return postprocess(self.raw(board, view), view["sensor"])

    def close(self) -> None:
        for _, _, renderer in self._scenes.values():
            renderer.close()
        self._scenes.clear()

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _index(classes: tuple, value) -> int | None:
    return classes.index(value) if value in classes else None


def make_label(board: dict, view: dict) -> dict:
    """The JSON label of one image (see the module docstring)."""
    true = CameraCalibration.from_json(view["camera_true"])
    x, y = board["x"], board["y"]
    top = true.project(np.array([x, y, constants.HOLE_DEPTH]))
    table = true.project(np.array([x, y, 0.0]))
    size_mm = round(board["size"] * 1000.0, 6)
    return {
        "board": {k: board[k] for k in ("shape", "size", "x", "y", "yaw")},
        "yaw_mod": yaw_mod(board["shape"], board["yaw"]),
        "shape_class": _index(SHAPE_CLASSES, board["shape"]),
        "size_class": _index(SIZES_MM, size_mm),
        "hole_px": [float(v) for v in top],
        "hole_px_table": [float(v) for v in table],
        "calibration": view["calibration"],
        "view": view,
    }


def draw(config: SplitConfig, index: int) -> tuple[dict, dict]:
    """(board, view) of image `index` of a split: from `default_rng([seed, index])` alone."""
    rng = np.random.default_rng([config.seed, index])
    board = sample_board(rng, config.shapes, config.sizes_mm)
    return board, sample_view(rng, board, config.condition, config.width, config.height)


def _png_write(path: Path, rgb: np.ndarray) -> None:
    from PIL import Image

    image = Image.fromarray(rgb)
    outdir.write_atomic(path, lambda tmp: image.save(tmp, format="PNG", compress_level=1))


def read_png(path: str | os.PathLike) -> np.ndarray:
    """(H, W, 3) uint8 RGB of a PNG/JPEG file; ValueError (one line) if missing or unreadable."""
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    if not path.exists():
        raise UsageError(f"image {path} does not exist")
    data = inputs.read_bytes(path, MAX_IMAGE_BYTES)  # a regular file: a FIFO never blocks
    try:
        with Image.open(io.BytesIO(data)) as im:
            if im.width * im.height > MAX_IMAGE_PIXELS:
                raise UsageError(f"image {path} is {im.width} x {im.height} px, too large")
            return np.asarray(im.convert("RGB"), dtype=np.uint8)
    except (OSError, UnidentifiedImageError, Image.DecompressionBombError, ValueError) as e:
        if isinstance(e, UsageError):
            raise
        raise UsageError(f"cannot read image {path}: not an image file") from None


@dataclass(frozen=True)
class SplitConfig:
    count: int
    seed: int
    condition: str = "nominal"
    width: int = 1280
    height: int = 960
    shapes: tuple[str, ...] = SHAPE_CLASSES
    sizes_mm: tuple[float, ...] = SIZES_MM

    def __post_init__(self):
        object.__setattr__(self, "shapes", tuple(self.shapes))
        object.__setattr__(self, "sizes_mm", tuple(float(s) for s in self.sizes_mm))
        if not self.shapes or not set(self.shapes) <= set(constants.SHAPES):
            raise UsageError(
                f"shapes must be some of {', '.join(constants.SHAPES)}, got {self.shapes}"
            )
        lo, hi = (1000.0 * s for s in constants.SIZE_RANGE)
        if not self.sizes_mm or not all(lo <= s <= hi for s in self.sizes_mm):
            raise UsageError(f"sizes must lie in [{lo:g}, {hi:g}] mm, got {self.sizes_mm}")
        if self.condition not in CONDITIONS:
            raise UsageError(
                f"unknown condition {self.condition!r}: choose from {', '.join(CONDITIONS)}"
            )
        if self.count < 1 or self.seed < 0:
            raise UsageError("count must be >= 1 and seed >= 0")
        if not (64 <= self.width <= 2048 and 64 <= self.height <= 2048):
            raise UsageError("image width and height must lie in 64..2048 px")

    def to_json(self) -> dict:
        doc = {k: getattr(self, k) for k in ("count", "seed", "condition", "width", "height")}
        return doc | {"shapes": list(self.shapes), "sizes_mm": list(self.sizes_mm)}


def _recorded(doc: dict) -> dict:
    """The SplitConfig a manifest records, as JSON; ValueError if it is not a split's."""
    if doc.get("schema") != SCHEMA or not isinstance(doc["config"], dict):
        raise ValueError(f"no {SCHEMA} manifest")
    # splits made before these options existed
    return {"shapes": list(SHAPE_CLASSES), "sizes_mm": list(SIZES_MM), **doc["config"]}


def prepare_split(out, config: SplitConfig, force: bool = False, note=None) -> Path:
    """Create the split directory with its manifest, or resume a split of the same config (its
    image count may change); with `force` a split of any config is moved aside (`note` is told
    where)."""
    split = OutDir(out, MANIFEST, "vision split", read=_recorded, ignore=("count",))
    plan = split.plan(config.to_json(), force)
    doc = {"schema": SCHEMA, "config": config.to_json()}
    split.prepare(plan, json.dumps(doc) + "\n", note)
    return split.path


def render_split(out, config: SplitConfig, progress: bool = True) -> int:
    """Render every image of the split not yet on disk; returns how many were rendered."""
    from tqdm import tqdm

    out = prepare_split(out, config)
    todo = [k for k in range(config.count) if not (out / f"{k:06d}.json").is_file()]
    with (
        Renderer(config.width, config.height) as renderer,
        tqdm(
            total=config.count,
            initial=config.count - len(todo),
            unit="img",
            desc=f"rendering {out.name}",
            disable=not progress,
            dynamic_ncols=True,
        ) as bar,
    ):
        for k in todo:
            board, view = draw(config, k)
            _png_write(out / f"{k:06d}.png", renderer.image(board, view))
            write_json(out / f"{k:06d}.json", make_label(board, view), indent=None)
            bar.update(1)
    return len(todo)


def split_config(split_dir) -> SplitConfig:
    """The SplitConfig of a split directory (ValueError if it is not one)."""
    path = Path(split_dir) / MANIFEST
    if not path.is_file():
        raise UsageError(f"{split_dir} holds no {MANIFEST}: not a vision split")
    doc = inputs.read_json(path, "a vision split manifest")
    try:
        return SplitConfig(**_recorded(doc))
    except (ValueError, KeyError, TypeError, AttributeError):
        raise UsageError(f"{path} is not a vision split manifest") from None


def check_trainable(config: SplitConfig, flag: str) -> None:
    """UsageError unless a split renders only the localizer's classes (it learns to name them)."""
    shapes = [s for s in config.shapes if s not in SHAPE_CLASSES]
    sizes = [f"{s:g} mm" for s in config.sizes_mm if s not in SIZES_MM]
    if shapes or sizes:
        raise UsageError(
            f"{flag} renders {', '.join(shapes + sizes)}: the localizer learns the shapes "
            f"{', '.join(SHAPE_CLASSES)} at {', '.join(f'{s:g}' for s in SIZES_MM)} mm only"
        )


def _number(value) -> bool:
    return type(value) in (int, float) and math.isfinite(value)


def label_problem(label) -> str | None:
    """What makes `label` (one image's JSON) unusable, or None: the fields the localizer's
    training, evaluation and figures read, with their types and ranges."""
    if not isinstance(label, dict):
        return "not a JSON object"
    board = label.get("board")
    if not isinstance(board, dict):
        return "board is not an object"
    if board.get("shape") not in constants.SHAPES:
        return f"board.shape is not one of {', '.join(constants.SHAPES)}"
    if not all(_number(board.get(k)) for k in ("size", "x", "y", "yaw")) or board["size"] <= 0:
        return "board.size, x, y and yaw are not numbers (size > 0)"
    for key, names in (("shape_class", SHAPE_CLASSES), ("size_class", SIZES_MM)):
        index = label.get(key)  # null: a part outside the localizer's classes
        if index is not None and (type(index) is not int or not 0 <= index < len(names)):
            return f"{key} is not null or an index below {len(names)}"
    if label.get("yaw_mod") is not None and not _number(label["yaw_mod"]):
        return "yaw_mod is not a number"
    px = label.get("hole_px")
    if not (isinstance(px, list) and len(px) == 2 and all(_number(v) for v in px)):
        return "hole_px is not two numbers"
    view = label.get("view")
    if not (isinstance(view, dict) and isinstance(view.get("distractors"), list)):
        return "view is not an object with distractors"
    if not (isinstance(view.get("table"), dict) and isinstance(view["table"].get("texture"), str)):
        return "view.table.texture is not a name"
    try:
        CameraCalibration.from_json(label.get("calibration"))
        CameraCalibration.from_json(view.get("camera_true"))
    except UsageError as e:
        return str(e)
    return None


def split_items(split_dir) -> list[tuple[Path, dict]]:
    """(png path, label) of every finished image of a split, in index order."""
    split_dir = Path(split_dir)
    config = split_config(split_dir)
    items = []
    for k in range(config.count):
        label_path = split_dir / f"{k:06d}.json"
        if label_path.exists():
            label = inputs.read_json(label_path, "a label file")
            why = label_problem(label)
            if why:
                raise UsageError(f"{label_path} is not a label file ({why})")
            items.append((split_dir / f"{k:06d}.png", label))
    if not items:
        raise UsageError(f"{split_dir} holds no rendered images yet")
    return items
