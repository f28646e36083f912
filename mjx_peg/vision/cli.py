"""`mjx-peg-vision` (= `python -m mjx_peg.vision`) render|train|evaluate|localize|act|figures.

    mjx-peg-vision render --out runs/vision/data/train --count 3000 --seed 0
    mjx-peg-vision render --out runs/vision/data/test --count 1000 --seed 2
    mjx-peg-vision train --data runs/vision/data/train --val runs/vision/data/val \
        --out runs/vision/model
    mjx-peg-vision evaluate --model runs/vision/model --data runs/vision/data/test \
        --out runs/vision/eval/test
    mjx-peg-vision localize IMAGE.png --camera CALIB.json [--model runs/vision/model]
    mjx-peg-vision act --policy paper --out runs/vision/act
    mjx-peg-vision figures --model runs/vision/model --data runs/vision/data/test

`evaluate`, `localize`, `act` and `figures` read the shipped localizer (`policies/localizer`)
unless --model names another; `train` writes to runs/vision/model. The README's command-line
rules hold: bad input (a missing image, a calibration without intrinsics, a flag out of its
range) is one line on stderr and exit status 2 before anything is written; --out is never an
input; `render` and `train` resume a directory made with the same
options; an earlier result is replaced only with --force, which moves it aside.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from mjx_peg import cli, outdir
from mjx_peg.errors import UsageError
from mjx_peg.policy.shipped import SHIPPED_DIR, resolve_policy
from mjx_peg.skill.search import SKILL_DESCRIPTIONS

PROG = "mjx-peg-vision"
TRAIN_OUT = Path("runs/vision/model")  # where `train` writes a new localizer
SHIPPED_MODEL = SHIPPED_DIR / "localizer"  # the localizer the other commands read by default
COUNT = cli.integer(1, 1_000_000)  # images in a split
PIXELS = cli.integer(64, 2048)  # image width, height
STEPS = cli.integer(1, 1_000_000)  # training steps of one network


def _note(text: str) -> None:
    """A one-line notice of this command on stderr."""
    cli.note(PROG, text)


def _csv(text: str) -> tuple[str, ...]:
    return tuple(s.strip() for s in text.split(",") if s.strip())


def _force(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument(
        "--force",
        action="store_true",
        help=f"replace {what} in --out: the earlier one is moved aside (NAME.replaced-DATE-TIME)",
    )


_MODEL = {
    "type": cli.nonempty_path,
    "default": SHIPPED_MODEL,
    "help": "localizer directory (model.json + model.npz); default: the shipped policies/localizer",
}


def build_parser() -> argparse.ArgumentParser:
    p = cli.Parser(prog=PROG, description="Localize the hole from a bird's-eye image (paper 6.6).")
    sub = p.add_subparsers(dest="command", required=True, parser_class=cli.Parser)
    path = cli.nonempty_path

    r = sub.add_parser("render", help="render a randomized, labelled split (PNG + JSON)")
    r.add_argument("--out", type=path, required=True, help="split directory (resumed if the same)")
    r.add_argument("--count", type=COUNT, required=True, help="images in the split")
    r.add_argument("--seed", type=cli.SEED, default=0, help="image k uses default_rng([seed, k])")
    r.add_argument("--condition", choices=("nominal", "dark", "camera-off"), default="nominal")
    r.add_argument("--width", type=PIXELS, default=1280, help="default 1280")
    r.add_argument("--height", type=PIXELS, default=960, help="default 960")
    r.add_argument(
        "--shapes",
        default="circle,square,triangle",
        help="comma-separated, of circle, square, triangle, hexagon, rectangle (the localizer "
        "learns the first three)",
    )
    r.add_argument(
        "--sizes",
        default="25,50,60",
        help="sizes S in mm, each in 10..80 (the localizer learns 25, 50, 60)",
    )
    _force(r, "an earlier split (any options)")

    t = sub.add_parser("train", help="train the localizer (CPU), export npz + json")
    t.add_argument("--data", type=path, required=True, help="training split")
    t.add_argument("--val", type=path, help="validation split (its numbers go into model.json)")
    t.add_argument("--out", type=path, default=TRAIN_OUT, help="model directory (resumed)")
    t.add_argument("--detector-steps", type=STEPS, help="default 1500")
    t.add_argument("--regressor-steps", type=STEPS, help="default 4000")
    t.add_argument("--batch", type=cli.integer(1, 4096), help="default 64")
    t.add_argument("--crops", type=cli.integer(1, 64), help="hole views per image, default 4")
    t.add_argument("--seed", type=cli.SEED, help="default 0")
    _force(t, "an earlier localizer (any options)")

    e = sub.add_parser("evaluate", help="error percentiles of a localizer on a split")
    e.add_argument("--model", **_MODEL)
    e.add_argument("--data", type=path, required=True, help="split to evaluate on")
    e.add_argument("--out", type=path, required=True, help="report directory")
    _force(e, "summary.md, metrics.json and errors.csv")

    lo = sub.add_parser("localize", help="one image + calibration -> hole estimate (JSON)")
    lo.add_argument("image", type=path, help="PNG or JPEG from the calibrated camera")
    lo.add_argument("--camera", type=path, required=True, help="calibration JSON (camera.py)")
    lo.add_argument("--model", **_MODEL)
    lo.add_argument(
        "--shape",
        help="the part's shape, when known: its yaw is read at that shape's symmetry; a shape "
        "the localizer cannot localize is refused (default: the shape it classifies)",
    )

    a = sub.add_parser("act", help="vision to action: trials with the localizer's estimates")
    a.add_argument("--model", **_MODEL)
    a.add_argument(
        "--policy",
        default="baseline",
        help="run directory with policy.npz, a shipped policy's name (policies/), or baseline",
    )
    a.add_argument("--out", type=path, required=True)
    a.add_argument("--shapes", default="circle,square", help="comma-separated")
    a.add_argument("--size", type=cli.SIZE_MM, default=50.0, help="S, one of 25, 50, 60")
    a.add_argument("--trials", type=cli.TRIALS, default=200, help="per shape, default 200")
    a.add_argument("--time-limit", type=cli.TIME_LIMIT_S, default=60.0, help="per trial")
    a.add_argument("--seed", type=cli.SEED, default=0)
    a.add_argument("--threads", type=cli.THREADS, help="engine lanes (default: every core)")
    cli.add_skill_option(a, SKILL_DESCRIPTIONS)
    _force(a, "trials.csv, summary.md and summary.json")

    f = sub.add_parser("figures", help="README pictures: predictions drawn, randomization gallery")
    f.add_argument("--model", **_MODEL)
    f.add_argument("--data", type=path, required=True, help="split to draw from")
    f.add_argument("--out", type=path, default=Path("docs/vision"))
    _force(f, "predictions.png and gallery.png")

    for sp in (r, t, e, a, f):
        sp.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def _warn_gl() -> None:
    from mjx_peg.world import gl

    if gl.fallback_note():
        cli.note(PROG, f"warning: {gl.fallback_note()}")


def _render(args) -> str:
    from mjx_peg.vision.dataset import SplitConfig, prepare_split, render_split
    from mjx_peg.world import mujoco_log
    from mjx_peg.world.constants import SHAPES, SIZE_RANGE

    lo, hi = (1000.0 * s for s in SIZE_RANGE)
    sizes = []
    for s in _csv(args.sizes):
        try:
            size = float(s)
        except ValueError:
            size = math.nan
        if not lo <= size <= hi:
            raise UsageError(f"--sizes must be sizes S in mm, each in [{lo:g}, {hi:g}], got "
                             f"{s[:20]!r}")  # fmt: skip
        sizes.append(size)
    shapes = _csv(args.shapes)
    for shape in shapes:
        if shape not in SHAPES:
            raise UsageError(
                f"--shapes must name shapes of {', '.join(SHAPES)}, got {shape[:20]!r}"
            )
    for flag, values in (("--sizes", sizes), ("--shapes", shapes)):
        if not values or len(set(values)) != len(values):
            given = getattr(args, flag[2:])[:40]
            raise UsageError(f"{flag} must name distinct values, got {given!r}")
    config = SplitConfig(
        count=args.count,
        seed=args.seed,
        condition=args.condition,
        width=args.width,
        height=args.height,
        shapes=shapes,
        sizes_mm=tuple(sizes),
    )
    with outdir.exclusive(args.out):
        prepare_split(args.out, config, force=args.force, note=_note)
        mujoco_log.send_to(args.out)
        _warn_gl()
        n = render_split(args.out, config, progress=not args.no_progress)
    return f"rendered {n} images ({config.count} in the split) into {args.out}"


def _train(args) -> str:
    import dataclasses

    from mjx_peg.vision.dataset import check_trainable, split_config, split_items
    from mjx_peg.vision.training import VisionTrainConfig, prepare_out, train

    outdir.check_apart(args.out, {"--data": args.data, "--val": args.val})
    for flag, split in (("--data", args.data), ("--val", args.val)):
        if split is not None:  # a split of its classes with readable labels, before any work
            check_trainable(split_config(split), flag)
            split_items(split)
    cli.check_jax()  # the localizer trains on JAX
    keys = ("detector_steps", "regressor_steps", "batch", "crops", "seed")
    changes = {k: getattr(args, k) for k in keys if getattr(args, k) is not None}
    config = dataclasses.replace(VisionTrainConfig(), **changes)
    with outdir.exclusive(args.out):
        prepare_out(args.out, config, force=args.force, note=_note)
        loc = train(args.data, args.out, config, val_dir=args.val, progress=not args.no_progress)
    val = loc.config.get("validation")
    text = f"trained localizer in {args.out} ({loc.config['parameters']} parameters)"
    if val:
        text += f"; validation p99 position {val['pos_p99_mm']:.2f} mm"
        if val.get("yaw_p99_deg") is not None:
            text += f", yaw {val['yaw_p99_deg']:.2f} deg"
    return text


def _evaluate(args) -> str:
    from mjx_peg.vision.dataset import split_items
    from mjx_peg.vision.localizer import Localizer
    from mjx_peg.vision.metrics import REPORT_FILES, evaluate_to

    outdir.check_apart(args.out, {"--model": args.model, "--data": args.data})
    loc = Localizer.load(args.model)
    split_items(args.data)
    with outdir.exclusive(args.out):
        outdir.refuse_or_move([args.out / name for name in REPORT_FILES], args.force, _note)
        outdir.prepare_dir(args.out)
        report = evaluate_to(loc, args.data, args.out, progress=not args.no_progress)
    o = report["overall"]
    yaw = "-" if o["yaw_p99_deg"] is None else f"{o['yaw_p99_deg']:.2f}"
    return (
        f"{o['images']} images: position p50/p95/p99 {o['pos_p50_mm']:.2f}/{o['pos_p95_mm']:.2f}/"
        f"{o['pos_p99_mm']:.2f} mm, yaw p99 {yaw} deg, shape "
        f"{100 * o['shape_accuracy']:.1f} %, size {100 * o['size_accuracy']:.1f} %; "
        f"wrote {args.out}/summary.md"
    )


def _localize(args) -> str:
    from mjx_peg.vision.camera import CameraCalibration
    from mjx_peg.vision.dataset import read_png
    from mjx_peg.vision.localizer import Localizer

    loc = Localizer.load(args.model)
    if args.shape is not None:
        loc.check_shape(args.shape)
    image = read_png(args.image)
    calib = CameraCalibration.load(args.camera)
    return json.dumps(loc.localize(image, calib, shape=args.shape).to_json(), indent=2)


def _act(args) -> str:
    from mjx_peg.vision.forward import SIZES_MM
    from mjx_peg.vision.localizer import Localizer

    shapes = _csv(args.shapes)
    if not shapes or len(set(shapes)) != len(shapes):
        raise UsageError("--shapes must name distinct shapes")
    loc = Localizer.load(args.model)
    for s in shapes:
        loc.check_shape(s, "--shapes")
    if args.size not in SIZES_MM:
        raise UsageError(
            f"--size must be a size the localizer knows (25, 50, 60 mm), got {args.size:g}"
        )
    if not args.policy:
        raise UsageError("--policy must be a run directory or baseline, got an empty string")
    args.policy = resolve_policy(args.policy)
    outdir.check_apart(args.out, {"--model": args.model, "--policy": args.policy})
    from mjx_peg.vision.act import RESULT_FILES, run_act
    from mjx_peg.world import mujoco_log

    if args.policy != "baseline":
        from mjx_peg.policy.export import load_policy

        load_policy(args.policy)  # a readable policy, before --out is touched
    with outdir.exclusive(args.out):
        outdir.refuse_or_move([args.out / name for name in RESULT_FILES], args.force, _note)
        outdir.prepare_dir(args.out)
        mujoco_log.send_to(args.out)
        _warn_gl()
        options = {"threads": args.threads} if args.threads else {}
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
            time_limit_s=args.time_limit,
            skill=args.skill,
        )
    a = s["all"]
    return (
        f"vision {100 * a['vision_success']:.1f} %, sampled +-8 mm/+-12 deg "
        f"{100 * a['sampled_success']:.1f} %, exact pose {100 * a['exact_success']:.1f} %, "
        f"paper 92 %; wrote {args.out}/summary.md"
    )


def _figures(args) -> str:
    from mjx_peg.vision.dataset import split_items
    from mjx_peg.vision.figures import FIGURES, write_figures
    from mjx_peg.vision.localizer import Localizer

    outdir.check_apart(args.out, {"--model": args.model, "--data": args.data})
    loc = Localizer.load(args.model)
    split_items(args.data)
    with outdir.exclusive(args.out):
        outdir.refuse_or_move([args.out / name for name in FIGURES], args.force, _note)
        outdir.prepare_dir(args.out)
        _warn_gl()
        paths = write_figures(loc, args.data, args.out)
    return "wrote " + ", ".join(str(p) for p in paths)


@cli.entry(PROG, interrupted="interrupted; rerun the same command to resume")
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
    print(handlers[args.command](args))
    return 0
