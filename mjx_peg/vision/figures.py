"""README pictures: renders with the true and the predicted hole drawn, and a gallery.

python -m mjx_peg.vision figures --model runs/vision/model --data runs/vision/data/test
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.vision.dataset import read_png, split_items
from mjx_peg.vision.localizer import Localizer
from mjx_peg.world import constants, parts

FIGURES = ("predictions.png", "gallery.png")


def _block_mean(image: np.ndarray, k: int) -> np.ndarray:
    """(H/k, W/k, 3) uint8: the image averaged over k x k blocks (a thumbnail)."""
    h, w = (image.shape[0] // k) * k, (image.shape[1] // k) * k
    blocks = image[:h, :w].reshape(h // k, k, w // k, k, 3).astype(np.float32)
    return blocks.mean(axis=(1, 3)).round().astype(np.uint8)


def _save(fig, path: Path, dpi: int) -> Path:
    """Write a figure as a PNG with a 256-colour adaptive palette (a quarter of the bytes for
    renders), atomically; closes the figure."""
    import matplotlib.pyplot as plt
    from PIL import Image

    from mjx_peg import outdir

    def write(tmp: Path) -> None:
        fig.savefig(tmp, dpi=dpi, format="png")
        with Image.open(tmp) as im:
            paletted = im.convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE)
        paletted.save(tmp, format="PNG", optimize=True)

    try:
        return outdir.write_atomic(path, write)
    finally:
        plt.close(fig)


def hole_outline(
    shape: str, size: float, x: float, y: float, yaw: float, hole_scale: float | None = None
) -> np.ndarray:
    """(n + 1, 3) closed outline of the hole's rim at the board top, world frame."""
    corners = parts.hole_corners(shape, size, hole_scale)
    corners = np.concatenate([corners, corners[:1]])
    c, s = math.cos(yaw), math.sin(yaw)
    return np.stack(
        [
            x + c * corners[:, 0] - s * corners[:, 1],
            y + s * corners[:, 0] + c * corners[:, 1],
            np.full(len(corners), constants.HOLE_DEPTH),
        ],
        axis=-1,
    )


def _draw(ax, calib: CameraCalibration, shape, size, x, y, yaw, color, label, **style):
    uv = calib.project(hole_outline(shape, size, x, y, yaw))
    ax.plot(uv[:, 0], uv[:, 1], color=color, label=label, **style)
    c = calib.project(np.array([x, y, constants.HOLE_DEPTH]))
    ax.plot([c[0]], [c[1]], "+", color=color, ms=10, mew=1.6)


def predictions_png(localizer: Localizer, items, path: Path) -> Path:
    """Three renders (one per shape when possible), whole and zoomed, true (green) and
    predicted (magenta) hole outlines and centres drawn through the camera."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    picks, seen = [], set()
    for png, label in items:
        if label["board"]["shape"] not in seen:
            seen.add(label["board"]["shape"])
            picks.append((png, label))
        if len(picks) == 3:
            break
    fig, axes = plt.subplots(2, len(picks), figsize=(4.2 * len(picks), 7.0))
    axes = np.atleast_2d(axes).reshape(2, -1)
    for col, (png, label) in enumerate(picks):
        image = read_png(png)
        calib = CameraCalibration.from_json(label["calibration"])
        true_cam = CameraCalibration.from_json(label["view"]["camera_true"])
        result = localizer.localize(image, calib)
        b, e = label["board"], result.estimate
        err = 1000 * math.hypot(e.x - b["x"], e.y - b["y"])
        for row in range(2):
            ax = axes[row, col]
            ax.imshow(image)
            _draw(
                ax,
                true_cam,
                b["shape"],
                b["size"],
                b["x"],
                b["y"],
                b["yaw"],
                "lime",
                "true",
                lw=3.0,
            )
            _draw(
                ax, calib, e.shape, e.size, e.x, e.y, e.yaw, "magenta", "predicted", lw=1.2, ls="--"
            )
            ax.set_xticks([])
            ax.set_yticks([])
            if row == 1:
                u, v = label["hole_px"]
                half = 70
                ax.set_xlim(u - half, u + half)
                ax.set_ylim(v + half, v - half)
            else:
                ax.set_title(
                    f"{b['shape']} {1000 * b['size']:g} mm -> {e.shape} "
                    f"{1000 * e.size:g} mm\nerror {err:.2f} mm",
                    fontsize=9,
                )
        if col == 0:
            axes[0, 0].legend(loc="lower left", fontsize=8)
    fig.suptitle(
        "Localizer on held-out renders: true hole (green), predicted (magenta)", fontsize=10
    )
    fig.tight_layout()
    return _save(fig, path, dpi=90)


def gallery_png(items, path: Path, count: int = 12) -> Path:
    """A grid of renders (the randomization at a glance), each labelled with its draw."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    picks = items[:count]
    cols = 4
    rows = math.ceil(len(picks) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.55 * rows))
    for ax in np.ravel(axes):
        ax.axis("off")
    for ax, (png, label) in zip(np.ravel(axes), picks, strict=False):
        ax.imshow(_block_mean(read_png(png), 4))
        v = label["view"]
        n = len(v["distractors"])
        ax.set_title(
            f"{label['board']['shape']} {1000 * label['board']['size']:g} mm, "
            f"{v['table']['texture']} table, {n} distractor{'' if n == 1 else 's'}",
            fontsize=7,
        )
    fig.tight_layout()
    return _save(fig, path, dpi=80)


def write_figures(localizer: Localizer, split_dir, out_dir) -> list[Path]:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    items = split_items(split_dir)
    return [
        predictions_png(localizer, items, out / "predictions.png"),
        gallery_png(items, out / "gallery.png"),
    ]
