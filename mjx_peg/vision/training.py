"""Train the localizer (Flax + Optax on the CPU), checkpoint with Orbax, export npz + json.

    python -m mjx_peg.vision train --data runs/vision/data/train --val runs/vision/data/val \
        --out runs/vision/model

1. Views (`views.py`) are cut once from every training image through its calibration and kept
   as uint8 arrays (cached in --out/cache/): the workspace view per image, and `crops` fine views
   per image centred at the true hole plus a uniform offset of up to +-`crop_offset_mm` per
   axis (what the detector's error leaves to the regressor).
2. The detector trains first (softmax cross-entropy over the 48 mm cells + L1 on the in-cell
   offset), then the regressor (smooth L1 on the offset, L1 on the yaw encoding of the true
   shape's symmetry, cross-entropy on shape and size). Augmentation: mirror images, with the
   labels mirrored exactly (offset sign; yaw -> -yaw, and for the triangle's encoding
   (c3, s3) -> (-c3, s3) under y -> -y).
3. Orbax checkpoints every `checkpoint_every` steps (--out/checkpoints/); rerunning the same
   command resumes. At the end: model.npz + model.json (the portable export, `Localizer.load`),
   metrics.csv (losses), validation numbers in model.json.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import math
import time
from pathlib import Path

import numpy as np

from mjx_peg.outdir import OutDir, write_npz
from mjx_peg.vision import forward
from mjx_peg.vision.camera import CameraCalibration
from mjx_peg.vision.dataset import read_png, split_items
from mjx_peg.vision.forward import SHAPE_CLASSES
from mjx_peg.vision.localizer import SCHEMA, SCHEMA_VERSION, Localizer, default_workspace
from mjx_peg.vision.views import ViewConfig, coarse_view, fine_view
from mjx_peg.world.constants import SIZES_MM

CONFIG_FILE, METRICS_FILE, CHECKPOINTS, CACHE = (
    "train_config.json",
    "metrics.csv",
    "checkpoints",
    "cache",
)


@dataclasses.dataclass(frozen=True)
class VisionTrainConfig:
    """Everything that determines a trained localizer (train_config.json)."""

    arch: dict = dataclasses.field(
        default_factory=lambda: json.loads(json.dumps(forward.DEFAULT_ARCH))
    )
    crops: int = 4  # fine views per training image
    crop_offset_mm: float = 15.0  # +- per axis, uniform
    batch: int = 64
    detector_steps: int = 1500
    regressor_steps: int = 4000
    learning_rate: float = 2e-3
    weight_decay: float = 1e-4
    warmup_steps: int = 100
    checkpoint_every: int = 500
    refine: int = 2  # regressor passes at inference
    seed: int = 0

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, doc: dict) -> VisionTrainConfig:
        return cls(**doc)


# --- the view cache ---------------------------------------------------------------------------


def _cut(job) -> tuple[np.ndarray, np.ndarray]:
    """(coarse view, fine views) of one image: job = (png, calibration JSON, views JSON,
    fine view centres (crops, 2))."""
    png, calib_doc, views_doc, centres = job
    views = ViewConfig.from_json(views_doc)
    image = read_png(png)
    calib = CameraCalibration.from_json(calib_doc)
    coarse = np.rint(coarse_view(image, calib, views)).astype(np.uint8)
    fine = [np.rint(fine_view(image, calib, c, views)).astype(np.uint8) for c in centres]
    return coarse, np.stack(fine)


def build_views(
    items,
    views: ViewConfig,
    crops: int,
    crop_offset_m: float,
    seed: int,
    progress: bool = True,
    workers: int | None = None,
) -> dict[str, np.ndarray]:
    """Views and targets of (png path, label) items (see the module docstring), cut by
    `workers` threads (default: one per core; PNG decoding is most of the cost)."""
    import os
    from concurrent.futures import ThreadPoolExecutor

    from tqdm import tqdm

    rng = np.random.default_rng(seed)
    n = len(items)
    true = np.array([[lb["board"]["x"], lb["board"]["y"]] for _, lb in items]).reshape(n, 2)
    centres = true[:, None] + rng.uniform(-crop_offset_m, crop_offset_m, (n, crops, 2))
    jobs = [
        (str(png), lb["calibration"], views.to_json(), centres[i])
        for i, (png, lb) in enumerate(items)
    ]
    out = {
        "coarse": np.zeros((n, views.coarse_rows, views.coarse_cols, 3), np.uint8),
        "coarse_rc": views.world_to_coarse(true).astype(np.float32),
        "fine": np.zeros((n * crops, views.fine_size, views.fine_size, 3), np.uint8),
        # (true - view centre) / OFFSET_SCALE
        "offset": ((true[:, None] - centres) / forward.OFFSET_SCALE).reshape(-1, 2),
        "yaw": np.repeat([lb["board"]["yaw"] for _, lb in items], crops),
        "shape": np.repeat([lb["shape_class"] for _, lb in items], crops),
        "size": np.repeat([lb["size_class"] for _, lb in items], crops),
    }
    out["offset"] = out["offset"].astype(np.float32)
    out["yaw"] = out["yaw"].astype(np.float32)
    out["shape"] = out["shape"].astype(np.int32)
    out["size"] = out["size"].astype(np.int32)
    workers = workers or os.cpu_count() or 1
    bar = tqdm(total=n, desc="cutting views", unit="img", disable=not progress, dynamic_ncols=True)
    # Threads: PIL's PNG decoder and NumPy's gathers release the GIL (1.6x on 2 cores here).
    with bar, ThreadPoolExecutor(workers) as pool:
        for i, (coarse, fine) in enumerate(pool.map(_cut, jobs)):
            out["coarse"][i] = coarse
            out["fine"][i * crops : (i + 1) * crops] = fine
            bar.update(1)
    return out


def cached_views(
    split_dir,
    cache_dir,
    views: ViewConfig,
    crops: int,
    crop_offset_m: float,
    seed: int,
    progress: bool = True,
) -> dict[str, np.ndarray]:
    """`build_views` of a split, cached in cache_dir under a key of everything that shapes it."""
    items = split_items(split_dir)
    key = json.dumps(
        [str(Path(split_dir).resolve()), len(items), views.to_json(), crops, crop_offset_m, seed]
    )
    path = (
        Path(cache_dir)
        / f"{Path(split_dir).name}-{hashlib.sha1(key.encode()).hexdigest()[:12]}.npz"
    )
    if path.is_file():
        with np.load(path, allow_pickle=False) as npz:
            return {k: npz[k] for k in npz.files}
    arrays = build_views(items, views, crops, crop_offset_m, seed, progress)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_npz(path, arrays)
    return arrays


# --- JAX pieces --------------------------------------------------------------------------------


def _standardize(x):
    """views.standardize in jax.numpy, on uint8 batches (B, H, W, 3)."""
    import jax.numpy as jnp

    x = x.astype(jnp.float32)
    centred = x - x.mean(axis=(1, 2), keepdims=True)
    std = jnp.sqrt((centred**2).mean(axis=(1, 2, 3), keepdims=True))
    return centred / (std + 4.0)


_ONE_MIRROR = np.array([0.0, 1.0, 0.0, 1.0], np.float32)
_Y_MIRROR = np.array([0.0, 0.0, 1.0, 1.0], np.float32)


def mirror_encoding(enc, flip_rows, flip_cols):
    """(B, 4) yaw encodings (cos 4y, sin 4y, cos 3y, sin 3y) of holes seen in a view mirrored
    top-bottom (world x -> -x) and/or left-right (y -> -y); NumPy or JAX arrays.

    One mirror turns a square's yaw into -yaw (mod 90 deg) and a triangle's into -yaw (x -> -x)
    or 60 deg - yaw (y -> -y) (mod 120 deg); both mirrors are a half turn, which leaves the
    square alone and adds 60 deg (mod 120) to the triangle. tests/vision/test_vision.py checks this
    against the mirrored outlines.
    """
    one = (flip_rows ^ flip_cols)[:, None].astype(np.float32)
    ycol = flip_cols[:, None].astype(np.float32)
    return enc * (1.0 - 2.0 * one * _ONE_MIRROR) * (1.0 - 2.0 * ycol * _Y_MIRROR)


def _yaw_targets(yaw):
    import jax.numpy as jnp

    return jnp.stack([jnp.cos(4 * yaw), jnp.sin(4 * yaw), jnp.cos(3 * yaw), jnp.sin(3 * yaw)], -1)


def make_steps(config: VisionTrainConfig, views: ViewConfig):
    """(detector step, regressor step, detector/regressor modules, optimizer) jitted."""
    import jax
    import jax.numpy as jnp
    import optax

    from mjx_peg.vision.nets import build

    det, reg = build(config.arch)
    stride = views.coarse_stride
    h, w = views.coarse_cells

    def optimizer(steps: int):
        schedule = optax.warmup_cosine_decay_schedule(
            0.0, config.learning_rate, config.warmup_steps, max(steps, config.warmup_steps + 1)
        )
        return optax.chain(
            optax.clip_by_global_norm(1.0), optax.adamw(schedule, weight_decay=config.weight_decay)
        )

    det_opt, reg_opt = optimizer(config.detector_steps), optimizer(config.regressor_steps)

    def det_loss(params, x, rc, flip):
        x = _standardize(x)
        x = jnp.where(flip[:, None, None, None], x[:, :, ::-1], x)
        rc = jnp.where(flip[:, None], jnp.stack([rc[:, 0], views.coarse_cols - rc[:, 1]], -1), rc)
        out = det.apply({"params": params}, x)  # (B, h, w, 3)
        cell = jnp.clip(jnp.floor(rc / stride), 0, jnp.array([h - 1, w - 1])).astype(jnp.int32)
        idx = cell[:, 0] * w + cell[:, 1]
        logits = out[..., 0].reshape(out.shape[0], -1)
        ce = optax.softmax_cross_entropy_with_integer_labels(logits, idx).mean()
        at = out.reshape(out.shape[0], -1, 3)[jnp.arange(out.shape[0]), idx, 1:]
        frac = rc / stride - cell
        l1 = jnp.abs(jax.nn.sigmoid(at) - frac).sum(-1).mean()
        return ce + l1, {"ce": ce, "offset_l1": l1}

    def reg_loss(params, x, offset, yaw, shape, size, flip_r, flip_c):
        x = _standardize(x)
        x = jnp.where(flip_r[:, None, None, None], x[:, ::-1], x)
        x = jnp.where(flip_c[:, None, None, None], x[:, :, ::-1], x)
        sign = jnp.stack([jnp.where(flip_r, -1.0, 1.0), jnp.where(flip_c, -1.0, 1.0)], -1)
        offset = offset * sign  # view rows are world x, columns world y
        enc = mirror_encoding(_yaw_targets(yaw), flip_r, flip_c)
        out = reg.apply({"params": params}, x)
        pos = optax.huber_loss(out[:, :2], offset, delta=0.05).sum(-1).mean() / 0.05
        sq, tri = (shape == 1).astype(jnp.float32), (shape == 2).astype(jnp.float32)
        yaw_err = sq * jnp.abs(out[:, 2:4] - enc[:, :2]).sum(-1) + tri * jnp.abs(
            out[:, 4:6] - enc[:, 2:]
        ).sum(-1)
        yaw_l = yaw_err.sum() / jnp.maximum(sq.sum() + tri.sum(), 1.0)
        shape_ce = optax.softmax_cross_entropy_with_integer_labels(out[:, 6:9], shape).mean()
        size_ce = optax.softmax_cross_entropy_with_integer_labels(out[:, 9:12], size).mean()
        loss = pos + yaw_l + 0.2 * (shape_ce + size_ce)
        return loss, {"pos": pos, "yaw": yaw_l, "shape_ce": shape_ce, "size_ce": size_ce}

    @jax.jit
    def det_step(params, opt_state, x, rc, flip):
        (loss, aux), grads = jax.value_and_grad(det_loss, has_aux=True)(params, x, rc, flip)
        updates, opt_state = det_opt.update(grads, opt_state, params)
        return optax.apply_updates(params, updates), opt_state, loss, aux

    @jax.jit
    def reg_step(params, opt_state, x, offset, yaw, shape, size, flip_r, flip_c):
        (loss, aux), grads = jax.value_and_grad(reg_loss, has_aux=True)(
            params, x, offset, yaw, shape, size, flip_r, flip_c
        )
        updates, opt_state = reg_opt.update(grads, opt_state, params)
        return optax.apply_updates(params, updates), opt_state, loss, aux

    return det_step, reg_step, det, reg, det_opt, reg_opt


def init_params(module, input_shape: tuple[int, ...], rng: np.random.Generator) -> dict:
    """He-normal kernels (ReLU nets) and zero biases for a Flax module, drawn in NumPy.

    The shapes come from `jax.eval_shape`; drawing in NumPy avoids compiling JAX's random
    initializers, which took 10-20 s per network on this CPU (the training steps: ~3 s).
    """
    import jax

    shapes = jax.eval_shape(module.init, jax.random.key(0), np.zeros(input_shape, np.float32))
    params = {}
    for layer, leaves in shapes["params"].items():
        kernel = leaves["kernel"].shape
        fan_in = int(np.prod(kernel[:-1]))
        params[layer] = {
            "kernel": (rng.standard_normal(kernel) * np.sqrt(2.0 / fan_in)).astype(np.float32),
            "bias": np.zeros(leaves["bias"].shape, np.float32),
        }
    return params


# --- the loop ------------------------------------------------------------------------------------


def prepare_out(out, config: VisionTrainConfig, force: bool = False, note=None) -> Path:
    """Create --out with train_config.json, or resume a localizer of the same config there;
    with `force` one of any config is moved aside (`note` is told where)."""
    model = OutDir(out, CONFIG_FILE, "localizer")
    model.open(config.to_json(), force, note=note)
    return model.path


def train(
    data_dir,
    out_dir,
    config: VisionTrainConfig | None = None,
    val_dir=None,
    views: ViewConfig | None = None,
    progress: bool = True,
) -> Localizer:
    """Train (or resume) a localizer on the split `data_dir`; export it to out_dir."""
    from tqdm import tqdm

    from mjx_peg.learn.checkpoints import Checkpoints

    config = config or VisionTrainConfig()
    views = views or ViewConfig()
    out = Path(out_dir)
    prepare_out(out, config)
    t_start, cpu_start = time.perf_counter(), time.process_time()
    data = cached_views(
        data_dir,
        out / CACHE,
        views,
        config.crops,
        config.crop_offset_mm / 1000.0,
        config.seed,
        progress,
    )
    t_views = time.perf_counter() - t_start
    det_step, reg_step, det, reg, det_opt, reg_opt = make_steps(config, views)
    init_rng = np.random.default_rng([config.seed, 1])
    det_params = init_params(det, (1, views.coarse_rows, views.coarse_cols, 3), init_rng)
    reg_params = init_params(reg, (1, views.fine_size, views.fine_size, 3), init_rng)
    state = {
        "det": det_params,
        "reg": reg_params,
        "det_opt": det_opt.init(det_params),
        "reg_opt": reg_opt.init(reg_params),
        "step": np.zeros((), np.int64),  # detector steps, then regressor steps, in one count
    }
    saved = Checkpoints(out / CHECKPOINTS, keep=2, key_width=4)
    start = 0
    if saved.latest_step() is not None:
        state = saved.restore(state)
        start = int(state["step"])
    total = config.detector_steps + config.regressor_steps
    metrics_path = out / METRICS_FILE
    if start == 0 or not metrics_path.is_file():
        metrics_path.write_text("step,stage,loss,a,b,c,d\n")
    rng = np.random.default_rng([config.seed, start])
    n_img, n_crop = data["coarse"].shape[0], data["fine"].shape[0]
    b = config.batch
    with (
        saved,
        open(metrics_path, "a", newline="") as f,
        tqdm(
            total=total,
            initial=start,
            unit="step",
            desc="training localizer",
            disable=not progress,
            dynamic_ncols=True,
        ) as bar,
    ):
        writer = csv.writer(f)
        for step in range(start, total):
            if step < config.detector_steps:
                i = rng.integers(n_img, size=b)
                state["det"], state["det_opt"], loss, aux = det_step(
                    state["det"],
                    state["det_opt"],
                    data["coarse"][i],
                    data["coarse_rc"][i],
                    rng.uniform(size=b) < 0.5,
                )
                stage = "detector"
            else:
                i = rng.integers(n_crop, size=b)
                state["reg"], state["reg_opt"], loss, aux = reg_step(
                    state["reg"],
                    state["reg_opt"],
                    data["fine"][i],
                    data["offset"][i],
                    data["yaw"][i],
                    data["shape"][i],
                    data["size"][i],
                    rng.uniform(size=b) < 0.5,
                    rng.uniform(size=b) < 0.5,
                )
                stage = "regressor"
            done = step + 1
            if done % 25 == 0 or done == total:
                vals = [float(loss)] + [float(v) for v in aux.values()]
                writer.writerow([done, stage, *(f"{v:.5g}" for v in vals)])
                f.flush()
                bar.set_postfix(stage=stage, loss=f"{vals[0]:.3f}")
            bar.update(1)
            if done % config.checkpoint_every == 0 or done in (config.detector_steps, total):
                state["step"] = np.asarray(done, np.int64)
                f.flush()
                saved.save(done, state)
    wall, cpu = time.perf_counter() - t_start, time.process_time() - cpu_start
    from mjx_peg.vision.nets import flat_params

    params = {**flat_params("detector", state["det"]), **flat_params("regressor", state["reg"])}
    doc = {
        "schema": SCHEMA,
        "schema_version": SCHEMA_VERSION,
        "arch": config.arch,
        "views": views.to_json(),
        "refine": config.refine,
        "workspace": default_workspace(),
        "classes": {"shapes": list(SHAPE_CLASSES), "sizes_mm": [int(s) for s in SIZES_MM]},
        "offset_scale_m": forward.OFFSET_SCALE,
        "train_config": config.to_json(),
        "train_data": str(Path(data_dir)),
        "train_images": int(n_img),
        # Wall and CPU time of this process (views, both networks); None when resumed.
        "train_wall_s": round(wall, 1) if start == 0 else None,
        "train_cpu_s": round(cpu, 1) if start == 0 else None,
        "view_cutting_s": round(t_views, 1),
        "parameters": int(sum(v.size for v in params.values())),
    }
    localizer = Localizer(doc, params)
    if val_dir is not None:
        from mjx_peg.vision.metrics import evaluate_split

        report = evaluate_split(localizer, val_dir, progress=progress)
        doc["validation"] = {"split": str(val_dir), **report["overall"]}
    localizer.save(out)
    return localizer


def fmt_minutes(seconds: float) -> str:
    return f"{seconds / 60:.1f} min" if math.isfinite(seconds) else "-"
