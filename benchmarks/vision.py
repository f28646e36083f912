"""Vision costs on this machine: renders/s, localization latency, training steps/s.

    python benchmarks/vision.py [--model runs/vision/model] [--write]

- render: randomized 1280 x 960 bird's-eye images (MuJoCo's headless renderer + the sensor
  model + PNG write), the dataset's own path, one process;
- localize: `Localizer.localize` (NumPy, both stages, 2 regressor passes) on rendered images,
  median latency;
- train: detector and regressor Adam steps at batch 64 (jitted, after compile), the steps/s that
  set the training wall time.

Wall and CPU time are both given: on a shared machine the wall time depends on the neighbours.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")  # read once, when mujoco is first imported
# The localizer's convolutions are small matrix products: OpenBLAS's threads only contend on a
# busy 2-core machine (median 22 ms with one thread, 60-200 ms with its default threads here).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from _report import ROOT, cpu_name, write_section  # noqa: E402  (benchmarks/ is on sys.path)

from mjx_peg.vision import dataset  # noqa: E402


def bench_render(count: int) -> dict:
    config = dataset.SplitConfig(count=count, seed=12345)
    with tempfile.TemporaryDirectory() as tmp:
        dataset.render_split(Path(tmp) / "warm", dataset.SplitConfig(count=9, seed=777), False)
        wall, cpu = time.perf_counter(), time.process_time()
        dataset.render_split(Path(tmp) / "bench", config, progress=False)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return {"images": count, "wall_s": wall, "cpu_s": cpu}


def bench_localize(model: str, count: int) -> dict | None:
    from mjx_peg.vision.camera import CameraCalibration
    from mjx_peg.vision.localizer import Localizer

    if not (Path(model) / "model.npz").is_file():
        return None
    loc = Localizer.load(model)
    with tempfile.TemporaryDirectory() as tmp:
        dataset.render_split(Path(tmp), dataset.SplitConfig(count=count, seed=4242), False)
        items = dataset.split_items(tmp)
        images = [
            (dataset.read_png(p), CameraCalibration.from_json(lb["calibration"])) for p, lb in items
        ]
    loc.localize(*images[0])
    times = []
    for image, calib in images:
        t = time.perf_counter()
        loc.localize(image, calib)
        times.append(time.perf_counter() - t)
    return {
        "images": count,
        "median_s": float(np.median(times)),
        "p95_s": float(np.percentile(times, 95)),
    }


def bench_train(steps: int) -> dict:
    import jax

    from mjx_peg.vision.training import VisionTrainConfig, init_params, make_steps
    from mjx_peg.vision.views import ViewConfig

    config, views = VisionTrainConfig(), ViewConfig()
    det_step, reg_step, det, reg, det_opt, reg_opt = make_steps(config, views)
    rng = np.random.default_rng(0)
    b = config.batch
    dp = init_params(det, (1, views.coarse_rows, views.coarse_cols, 3), rng)
    rp = init_params(reg, (1, views.fine_size, views.fine_size, 3), rng)
    xd = rng.integers(0, 255, (b, views.coarse_rows, views.coarse_cols, 3), dtype=np.uint8)
    rc = rng.uniform(10, 100, (b, 2)).astype(np.float32)
    xr = rng.integers(0, 255, (b, views.fine_size, views.fine_size, 3), dtype=np.uint8)
    off = rng.normal(size=(b, 2)).astype(np.float32)
    yaw = rng.uniform(0, 6, b).astype(np.float32)
    cls = rng.integers(0, 3, b).astype(np.int32)
    flip = rng.uniform(size=b) < 0.5
    out = {}
    for name, step, params, opt, args in (
        ("detector", det_step, dp, det_opt.init(dp), (xd, rc, flip)),
        ("regressor", reg_step, rp, reg_opt.init(rp), (xr, off, yaw, cls, cls, flip, flip)),
    ):
        t = time.perf_counter()
        params, opt, loss, _ = step(params, opt, *args)
        jax.block_until_ready(loss)
        compile_s = time.perf_counter() - t
        wall, cpu = time.perf_counter(), time.process_time()
        for _ in range(steps):
            params, opt, loss, _ = step(params, opt, *args)
        jax.block_until_ready(loss)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        out[name] = {"steps": steps, "wall_s": wall, "cpu_s": cpu, "compile_s": compile_s}
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="runs/vision/model")
    p.add_argument("--renders", type=int, default=60)
    p.add_argument("--localize", type=int, default=30)
    p.add_argument("--train-steps", type=int, default=30)
    p.add_argument("--write", action="store_true", help="update BENCHMARKS.md")
    args = p.parse_args()
    r = bench_render(args.renders)
    lo = bench_localize(args.model, args.localize)
    tr = bench_train(args.train_steps)
    load = os.getloadavg()[0]
    lines = [
        "## Vision",
        "",
        f"Device: {cpu_name()}, {os.cpu_count()} logical cores; load average "
        f"{load:.1f} during the run (the machine is shared: wall times stretch with it, CPU "
        "times less). `mjx_peg.vision`, 1280 x 960 renders, batch 64.",
        "",
        "| what | wall | CPU | rate |",
        "|---|---:|---:|---:|",
        f"| render + sensor + PNG, {r['images']} images, one process | {r['wall_s']:.1f} s | "
        f"{r['cpu_s']:.1f} s | {r['images'] / r['wall_s']:.2f} renders/s "
        f"({r['images'] / r['cpu_s']:.2f} per CPU-s) |",
    ]
    for name, t in tr.items():
        lines.append(
            f"| {name} training step (compile {t['compile_s']:.1f} s) | "
            f"{1000 * t['wall_s'] / t['steps']:.0f} ms | {1000 * t['cpu_s'] / t['steps']:.0f} ms "
            f"| {64 * t['steps'] / t['wall_s']:.0f} samples/s |"
        )
    if lo is not None:
        lines.append(
            f"| localize one image (NumPy, OPENBLAS_NUM_THREADS="
            f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}; detector x2 + regressor x2) | "
            f"{1000 * lo['median_s']:.0f} ms median, {1000 * lo['p95_s']:.0f} ms p95 | | |"
        )
    lines += ["", "Reproduce: `python benchmarks/vision.py --write`", ""]
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_section(ROOT / "BENCHMARKS.md", "## Vision", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
