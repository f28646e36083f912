"""`python -m mjx_peg.vision render|train|evaluate|localize|act|figures`.

    python -m mjx_peg.vision render --out runs/vision/data/train --count 4000 --seed 0
    python -m mjx_peg.vision render --out runs/vision/data/test --count 1000 --seed 2
    python -m mjx_peg.vision train --data runs/vision/data/train --val runs/vision/data/val \
        --out runs/vision/model
    python -m mjx_peg.vision evaluate --model runs/vision/model --data runs/vision/data/test
    python -m mjx_peg.vision localize IMAGE.png --camera CALIB.json [--model runs/vision/model]
    python -m mjx_peg.vision act --model runs/vision/model --policy baseline --out runs/vision/act

Bad input (a missing image, a calibration without intrinsics, an unknown option) prints one
line on stderr and exits with status 2. Renders use MuJoCo's headless renderer (MUJOCO_GL=egl
unless set; osmesa works too).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from mjx_peg import cli

PROG = "python -m mjx_peg.vision"
DEFAULT_MODEL = "runs/vision/model"


def _csv(text: str) -> tuple[str, ...]:
    return tuple(s.strip() for s in text.split(",") if s.strip())


def build_parser() -> argparse.ArgumentParser:
    p = cli.Parser(prog=PROG, description="Localize the hole from a bird's-eye image (paper 6.6).")
    sub = p.add_subparsers(dest="command", required=True, parser_class=cli.Parser)

    r = sub.add_parser("render", help="render a randomized, labelled split (PNG + JSON)")
    r.add_argument("--out", required=True, help="split directory (resumed if it exists)")
    r.add_argument("--count", type=int, required=True, help="images in the split")
    r.add_argument("--seed", type=int, default=0, help="image k uses default_rng([seed, k])")
    r.add_argument("--condition", default="nominal", help="nominal, dark or camera-off")
    r.add_argument("--width", type=int, default=1280)
    r.add_argument("--height", type=int, default=960)
    r.add_argument("--shapes", default="circle,square,triangle")
    r.add_argument("--sizes", default="25,50,60", help="sizes S in mm (of 25, 50, 60)")

    t = sub.add_parser("train", help="train the localizer (CPU), export npz + json")
    t.add_argument("--data", required=True, help="training split")
    t.add_argument("--out", default=DEFAULT_MODEL, help="model directory (resumed if it exists)")
    t.add_argument("--val", help="validation split (numbers go into model.json)")
    t.add_argument("--detector-steps", type=int)
    t.add_argument("--regressor-steps", type=int)
    t.add_argument("--batch", type=int)
    t.add_argument("--crops", type=int, help="fine views per training image")
    t.add_argument("--seed", type=int)

    e = sub.add_parser("evaluate", help="error percentiles of a localizer on a split")
    e.add_argument("--model", default=DEFAULT_MODEL)
    e.add_argument("--data", required=True, help="split to evaluate on")
    e.add_argument("--out", help="report directory (default: MODEL/eval/<split name>)")

    lo = sub.add_parser("localize", help="one image + calibration -> hole estimate (JSON)")
    lo.add_argument("image", help="PNG or JPEG from the calibrated camera")
    lo.add_argument("--camera", required=True, help="calibration JSON (camera.py's format)")
    lo.add_argument("--model", default=DEFAULT_MODEL)

    a = sub.add_parser("act", help="vision to action: trials with the localizer's estimates")
    a.add_argument("--model", default=DEFAULT_MODEL)
    a.add_argument("--policy", default="baseline", help="run directory with policy.npz or baseline")
    a.add_argument("--out", required=True)
    a.add_argument("--shapes", default="circle,square")
    a.add_argument("--size", type=float, default=50.0, help="S in mm")
    a.add_argument("--trials", type=int, default=200, help="per shape")
    a.add_argument("--seed", type=int, default=0)
    a.add_argument("--workers", type=int, help="engine worker processes")

    f = sub.add_parser("figures", help="README pictures: predictions drawn, randomization gallery")
    f.add_argument("--model", default=DEFAULT_MODEL)
    f.add_argument("--data", required=True, help="split to draw from")
    f.add_argument("--out", default="docs/vision")
    f.add_argument("--no-progress", action="store_true")

    for sp in (r, t, e, a):
        sp.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def _render(args) -> str:
    from mjx_peg.vision.dataset import SplitConfig, render_split

    sizes = tuple(float(s) for s in _csv(args.sizes))
    config = SplitConfig(
        count=args.count,
        seed=args.seed,
        condition=args.condition,
        width=args.width,
        height=args.height,
        shapes=_csv(args.shapes),
        sizes_mm=sizes,
    )
    n = render_split(args.out, config, progress=not args.no_progress)
    return f"rendered {n} images ({config.count} in the split) into {args.out}"


def _train(args) -> str:
    import dataclasses

    from mjx_peg.vision.training import VisionTrainConfig, train

    changes = {
        k: getattr(args, k)
        for k in ("detector_steps", "regressor_steps", "batch", "crops", "seed")
        if getattr(args, k) is not None
    }
    for key, value in changes.items():
        if value < (0 if key == "seed" else 1):
            raise ValueError(f"--{key.replace('_', '-')} must be positive, got {value}")
    config = dataclasses.replace(VisionTrainConfig(), **changes)
    if not Path(args.data).is_dir():
        raise ValueError(f"--data {args.data} is not a directory")
    loc = train(args.data, args.out, config, val_dir=args.val, progress=not args.no_progress)
    val = loc.config.get("validation")
    text = f"trained localizer in {args.out} ({loc.config['parameters']} parameters)"
    if val:
        text += (
            f"; validation p99 position {val['pos_p99_mm']:.2f} mm, yaw "
            f"{val['yaw_p99_deg']:.2f} deg"
        )
    return text


def _evaluate(args) -> str:
    from mjx_peg.vision.localizer import Localizer
    from mjx_peg.vision.metrics import evaluate_to

    loc = Localizer.load(args.model)
    out = args.out or str(Path(args.model) / "eval" / Path(args.data).name)
    report = evaluate_to(loc, args.data, out, progress=not args.no_progress)
    o = report["overall"]
    return (
        f"{o['images']} images: position p50/p95/p99 {o['pos_p50_mm']:.2f}/{o['pos_p95_mm']:.2f}/"
        f"{o['pos_p99_mm']:.2f} mm, yaw p99 {o['yaw_p99_deg']:.2f} deg, shape "
        f"{100 * o['shape_accuracy']:.1f} %, size {100 * o['size_accuracy']:.1f} %; "
        f"wrote {out}/summary.md"
    )


def _localize(args) -> str:
    from mjx_peg.vision.camera import CameraCalibration
    from mjx_peg.vision.dataset import read_png
    from mjx_peg.vision.localizer import Localizer

    image = read_png(args.image)
    calib = CameraCalibration.load(args.camera)
    loc = Localizer.load(args.model)
    return json.dumps(loc.localize(image, calib).to_json(), indent=2)


def _act(args) -> str:
    from mjx_peg.vision.act import run_act
    from mjx_peg.vision.localizer import Localizer

    shapes = _csv(args.shapes)
    for s in shapes:
        if s not in ("circle", "square", "triangle"):
            raise ValueError(f"unknown shape {s!r}: choose from circle, square, triangle")
    if args.trials < 1:
        raise ValueError(f"--trials must be positive, got {args.trials}")
    if args.policy != "baseline" and not Path(args.policy).exists():
        raise ValueError(f"--policy {args.policy} does not exist (a run directory or baseline)")
    loc = Localizer.load(args.model)
    options = {"workers": args.workers} if args.workers else {}
    s = run_act(
        loc,
        args.policy,
        args.out,
        shapes,
        args.size / 1000.0,
        args.trials,
        args.seed,
        options,
        progress=not args.no_progress,
    )
    a = s["all"]
    return (
        f"vision {100 * a['vision_success']:.1f} %, sampled +-8 mm/+-12 deg "
        f"{100 * a['sampled_success']:.1f} %, paper 92 %; wrote {args.out}/summary.md"
    )


def _figures(args) -> str:
    from mjx_peg.vision.figures import write_figures
    from mjx_peg.vision.localizer import Localizer

    paths = write_figures(Localizer.load(args.model), args.data, args.out)
    return "wrote " + ", ".join(str(p) for p in paths)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    handlers = {
        "render": _render,
        "train": _train,
        "evaluate": _evaluate,
        "localize": _localize,
        "act": _act,
        "figures": _figures,
    }
    try:
        print(handlers[args.command](args))
    except cli.USER_ERRORS as exc:  # CalibrationError, ModelError: ValueErrors
        return cli.fail(f"{PROG} {args.command}", exc)
    except KeyboardInterrupt:
        cli.fail(f"{PROG} {args.command}", "interrupted; rerun the same command to resume")
        return cli.EXIT_INTERRUPTED
    return 0
