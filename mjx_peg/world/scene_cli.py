"""`mjx-peg-scene`: write the scene MJCF for one part (shape, size, hole scale) and a PNG of it."""

from __future__ import annotations

import argparse
import sys

from mjx_peg import cli, outdir
from mjx_peg.errors import UsageError
from mjx_peg.world import gl
from mjx_peg.world.constants import HOLE_SCALE, SHAPES

PROG = "mjx-peg-scene"


def _parse(argv) -> argparse.Namespace:
    from mjx_peg.world.parts import HOLE_SCALE_HELP, hole_scale_of, parse_hole_scale

    parser = cli.Parser(
        prog=PROG,
        description="Write the scene MJCF for one part (shape, size, hole scale) and a PNG of it.",
    )
    parser.add_argument("--shape", required=True, choices=SHAPES)
    parser.add_argument(
        "--size", required=True, type=cli.SIZE_MM, help="characteristic size S (D or L)"
    )
    parser.add_argument("--hole-scale", default="paper", help=HOLE_SCALE_HELP)
    parser.add_argument(
        "--out", required=True, type=cli.nonempty_path, help="output directory (created if needed)"
    )
    parser.add_argument("--camera", default="overview", help="camera name (default: overview)")
    parser.add_argument(
        "--width", type=cli.integer(16, 1280), default=960, help="PNG width in px (default 960)"
    )
    parser.add_argument(
        "--height", type=cli.integer(16, 960), default=720, help="PNG height in px (default 720)"
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the scene's .xml and .png in --out: the earlier ones are moved aside "
        "(NAME.replaced-DATE-TIME)",
    )
    args = parser.parse_args(argv)
    args.size_mm = args.size
    args.hole_scale = hole_scale_of(args.shape, parse_hole_scale(args.hole_scale))
    return args


@cli.entry(PROG)
def main(argv=None) -> int:
    args = _parse(argv)
    import mujoco  # after mjx_peg (world.gl), which chooses MuJoCo's GL back-end

    from mjx_peg.world import mujoco_log, render
    from mjx_peg.world.mjcf import build_mjcf
    from mjx_peg.world.pose_solver import demo_pose
    from mjx_peg.world.scene import load_model

    mujoco_log.send_to(None)  # no MUJOCO_LOG.TXT in the working directory
    size = args.size_mm / 1000.0
    scale = args.hole_scale
    fit = "" if scale == HOLE_SCALE[args.shape] else f"_hole{scale:g}"
    stem = f"scene_{args.shape}_{args.size_mm:g}mm{fit}"
    xml_path, png_path = args.out / f"{stem}.xml", args.out / f"{stem}.png"
    # Everything is checked and made before --out is touched; nothing replaced without --force.
    with outdir.exclusive(args.out):
        if args.out.is_dir() and not args.force:
            outdir.refuse_or_move([xml_path, png_path], False)
        xml = build_mjcf(args.shape, size, scale)
        model = load_model(args.shape, size, scale)
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, args.camera) < 0:
            names = ", ".join(model.camera(i).name for i in range(model.ncam))
            raise UsageError(f"unknown camera {args.camera!r}: valid cameras are {names}")
        render.check_backend()
        outdir.prepare_dir(args.out)
        outdir.refuse_or_move([xml_path, png_path], args.force, lambda text: cli.note(PROG, text))
        if gl.fallback_note():
            cli.note(PROG, f"warning: {gl.fallback_note()}")
        rgb = render.render_rgb(model, demo_pose(model), args.camera, args.width, args.height)
        outdir.write_all_atomic(
            [(xml_path, xml), (png_path, lambda path: render.save_png(path, rgb))]
        )
    print(xml_path)
    print(png_path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
