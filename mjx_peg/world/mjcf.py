"""The scene's MJCF for one part (shape, size, hole clearance): UR5e, table, board with a hole, peg.

Frames, names and units follow CONVENTIONS.md (SI units inside; the CLI takes mm). The part's
geometry (what S measures for each shape, the hole's clearance and walls, the peg's section, the
hole's depth, the paper's 80 mm for every part) is `parts.py`'s.

Scene contents
--------------
- The UR5e from ``scenes/ur5e.xml`` (standard DH; the wrist-3 body frame is DH frame 6, and the
  site ``flange`` sits at its origin). The arm makes no contacts and owns the only 6 dofs.
- Table: the plane z = 0 (geom ``table``).
- Board: body ``board``, a *plain fixed body* (no joint, not mocap). Its frame origin is on the
  hole axis at the table top; the board spans 0 <= z <= HOLE_DEPTH in that frame and the hole runs
  through it along z. The engines place it per trial by overwriting ``model.body_pos[board]``
  and ``model.body_quat[board]`` (``scene.set_board_pose``; the MJX engine writes the same two
  fields into its batched model). The hole is made only of boxes, one per edge of the
  hole polygon (`hole_walls`: each wall's outward normal angle, evenly spaced from -90 deg, and
  the distance of its inner face from the axis): the box's inner face lies on the edge line and
  the box is long enough to reach the neighbouring boxes at the board's outer outline (a regular
  polygon with the same normals whose inradius is ``board_half_width`` >= 0.1 m, at least
  0.05 m beyond the farthest wall), so the walls have no gaps; the board top is solid at least
  out to 0.1 m from the hole axis (the triangle's board looks like a three-bladed star: the box
  ends stick out past the outline's corners).
  Hole reference orientation: at board yaw 0 one hole edge is parallel to world x, on the -y side
  of the axis (square: edges along x and y; triangle: an edge along x at y = -r_in with the
  opposite corner on +y; hexagon: edges along x at y = +-r_in, corners on the x axis; rectangle:
  its long edges along x at y = +-hole_scale S/4; circle: a regular HOLE_SIDES-gon with one edge
  along x at y = -r_in).
- Peg: body ``peg``, child of the wrist-3 body; its frame has its origin at the grasp point and z
  along the peg away from the flange; it spans 0 <= z <= PEG_LENGTH. The nominal grasp is the
  identity relative to ``flange``; grasp errors overwrite ``body_pos[peg]`` = (0, 0, dz) and
  ``body_quat[peg]`` (``scene.set_grasp``). Square peg: a box of edge L; rectangle peg: a box
  S by S/2, its long edge along the peg x axis. Circle peg: a convex mesh prism with CIRCLE_SIDES
  sides and circumradius D/2 (MJX has no cylinder-box collision). Triangle peg: a convex mesh
  prism, equilateral with edge L, corners at -90, 30 and 150 deg about the peg z axis: with the
  tool pointing down at the hole's yaw, R = Rz(yaw) Rx(pi), this is the hole's triangle (Rx(pi)
  mirrors y). Hexagon peg: a convex mesh prism, corners at 0, 60, ..., 300 deg, S across flats.
  Whatever the section, the peg weighs PEG_MASS and has the inertia of a solid cylinder of
  diameter S (it is held rigidly; the paper gives neither).
- Sites: ``flange`` (wrist-3 origin), ``tcp`` (wrist-3, (0, 0, PEG_LENGTH)), ``ft`` (peg origin),
  ``peg_tip`` (peg, (0, 0, PEG_LENGTH)). Sensors ``ft_force`` and ``ft_torque`` on site ``ft``:
  MuJoCo's force/torque sensors, expressed in the ``ft`` frame; they report the wrench that the
  wrist-3 body exerts on the peg: a peg held still in free space, tool down, reads (0, 0, -m g)
  (m g upward in the world), and after taring, a peg pressed onto a surface with force F along its
  own +z reads (0, 0, +F). The external (contact) wrench on the peg at rest is minus the tared
  reading.
- Contacts: only peg-board and peg-table (peg contype=1 conaffinity=2; board and table contype=2
  conaffinity=1; arm 0/0), condim 3. The pair friction is the max of the two geoms' frictions;
  ``scene.set_friction`` writes the sliding friction of every geom in ``peg_geom_ids`` and
  ``board_geom_ids`` (the table keeps TABLE_FRICTION, so peg-table friction = max(mu, 0.3)).
- Geom groups: 0 table, 1 board walls, 2 arm and peg (all visible by default); sites are group 4.
- Cameras: ``birdseye`` (fixed at (0.35, 0, 1.3) looking straight down, image up = world +x;
  at 4:3 it covers about x in [-0.19, 0.89], y in [-0.72, 0.72]) and ``overview`` (a fixed 3/4
  view of the workspace).

Physics: 2 ms steps, implicitfast, pyramidal cone, Newton solver with 20 iterations and 10 line
search iterations, gravity on.
"""

from __future__ import annotations

import functools
import math
import pathlib
import xml.etree.ElementTree as ET

import numpy as np

from mjx_peg.world.constants import HOLE_DEPTH, HOLE_SCALE, PEG_LENGTH, PEG_MASS, TIMESTEP
from mjx_peg.world.parts import check_hole_scale, check_part, hole_walls, peg_section

BOARD_MIN_HALF_WIDTH = 0.1  # m: inradius of the board's outer outline (at least)
BOARD_MIN_WALL = 0.05  # m: wall thickness around the hole (at least)
DEFAULT_FRICTION = 0.5  # peg and board sliding friction until scene.set_friction is called
TABLE_FRICTION = 0.3
WRIST3_BODY = "wrist_3_link"
UR5E_XML = pathlib.Path(__file__).resolve().parents[2] / "scenes" / "ur5e.xml"


def _fmt(x: float) -> str:
    """A float written exactly enough for 1e-12 m / rad."""
    return repr(float(x)) if x != 0.0 else "0"


def _vec(*xs: float) -> str:
    return " ".join(_fmt(x) for x in xs)


def board_half_width(shape: str, size: float, hole_scale: float | None = None) -> float:
    """Inradius (m) of the board's outer outline: max(0.1 m, the farthest wall + 0.05 m)."""
    farthest = max(d for _, d in hole_walls(shape, size, hole_scale))
    return max(BOARD_MIN_HALF_WIDTH, farthest + BOARD_MIN_WALL)


def _look_at_xyaxes(eye, target) -> str:
    """MJCF `xyaxes` of a camera at `eye` looking at `target` with world z up in the image."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    return _vec(*right, *up)


def element(parent: ET.Element, tag: str, **attrs) -> ET.Element:
    """A child `tag` of `parent` with `attrs`, each value written as str() (MJCF attributes)."""
    return ET.SubElement(parent, tag, {k: str(v) for k, v in attrs.items()})


def _add_board(worldbody: ET.Element, shape: str, size: float, hole_scale: float) -> None:
    walls = hole_walls(shape, size, hole_scale)
    w = board_half_width(shape, size, hole_scale)
    half_len = w * math.tan(math.pi / len(walls))  # reaches the outer outline's corners
    board = element(worldbody, "body", name="board", pos="0.45 0.1 0")
    for k, (phi, r) in enumerate(walls):
        half_thick = 0.5 * (w - r)
        c = r + half_thick
        yaw = phi - 0.5 * math.pi  # box x along the edge, box y along the outward normal
        element(
            board,
            "geom",
            name=f"board_wall{k}",
            type="box",
            size=_vec(half_len, half_thick, 0.5 * HOLE_DEPTH),
            pos=_vec(c * math.cos(phi), c * math.sin(phi), 0.5 * HOLE_DEPTH),
            quat=_vec(math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw)),
            material="board",
            contype=2,
            conaffinity=1,
            condim=3,
            group=1,
            friction=_vec(DEFAULT_FRICTION, 0.005, 0.0001),
        )
    element(board, "site", name="hole", pos="0 0 0", size="0.005", rgba="0 1 0 1", group=4)


def _add_peg(wrist3: ET.Element, asset: ET.Element, shape: str, size: float) -> None:
    element(
        wrist3,
        "site",
        name="tcp",
        pos=_vec(0, 0, PEG_LENGTH),
        size="0.006",
        rgba="0 0.6 1 1",
        group=4,
    )
    peg = element(wrist3, "body", name="peg", pos="0 0 0", quat="1 0 0 0")
    radius = size / 2.0
    ixy = PEG_MASS * (3.0 * radius**2 + PEG_LENGTH**2) / 12.0
    izz = PEG_MASS * radius**2 / 2.0
    element(
        peg,
        "inertial",
        pos=_vec(0, 0, PEG_LENGTH / 2),
        mass=_fmt(PEG_MASS),
        diaginertia=_vec(ixy, ixy, izz),
    )
    common = dict(
        contype=1,
        conaffinity=2,
        condim=3,
        group=2,
        material="peg",
        friction=_vec(DEFAULT_FRICTION, 0.005, 0.0001),
    )
    if shape in ("square", "rectangle"):
        half_width = size / 2 if shape == "square" else size / 4
        box = _vec(size / 2, half_width, PEG_LENGTH / 2)
        element(
            peg, "geom", name="peg", type="box", size=box, pos=_vec(0, 0, PEG_LENGTH / 2), **common
        )
    else:
        corners = peg_section(shape, size)
        verts = [(x, y, z) for z in (0.0, PEG_LENGTH) for x, y in corners]
        element(asset, "mesh", name="peg_mesh", vertex=" ".join(_vec(*v) for v in verts))
        element(peg, "geom", name="peg", type="mesh", mesh="peg_mesh", **common)
    element(peg, "site", name="ft", pos="0 0 0", size="0.008", rgba="1 1 0 1", group=4)
    element(
        peg,
        "site",
        name="peg_tip",
        pos=_vec(0, 0, PEG_LENGTH),
        size="0.006",
        rgba="1 0 0 1",
        group=4,
    )


@functools.cache
def _arm_xml() -> str:
    return UR5E_XML.read_text()


def build_mjcf(shape: str, size: float, hole_scale: float | None = None) -> str:
    """The full scene's MJCF (a standalone XML string) for `shape` in SHAPES, `size` in m and
    the hole's clearance `hole_scale` (hole size / peg size; None: the shape's paper fit).

    size is the characteristic size S (`parts.py` says what it measures for each shape).
    Raises UsageError for an unknown shape, a size that is not a finite number > 0 or a hole
    scale outside HOLE_SCALE_RANGE.
    """
    shape, size = check_part(shape, size)
    scale = check_hole_scale(shape, hole_scale)
    root = ET.fromstring(_arm_xml())
    fit = "" if scale == HOLE_SCALE[shape] else f"_hole{scale:g}"
    root.set("model", f"mjx_peg_{shape}_{size * 1000:g}mm{fit}")

    compiler = root.find("compiler")
    root.remove(compiler)
    root.insert(0, compiler)
    option = ET.Element(
        "option",
        timestep=_fmt(TIMESTEP),
        integrator="implicitfast",
        cone="pyramidal",
        solver="Newton",
        iterations="20",
        ls_iterations="10",
        gravity="0 0 -9.81",
    )
    root.insert(1, option)
    visual = ET.Element("visual")
    element(visual, "global", offwidth=1280, offheight=960, azimuth=150, elevation=-25)
    element(
        visual, "headlight", ambient="0.35 0.35 0.35", diffuse="0.5 0.5 0.5", specular="0.1 0.1 0.1"
    )
    element(visual, "map", znear=0.01)
    root.insert(2, visual)
    asset = ET.Element("asset")
    grid = dict(rgb1="0.82 0.80 0.76", rgb2="0.74 0.72 0.68", mark="edge", markrgb="0.6 0.58 0.55")
    element(
        asset, "texture", name="grid", type="2d", builtin="checker", width=256, height=256, **grid
    )
    element(asset, "material", name="table", texture="grid", texrepeat="8 8", reflectance="0.05")
    element(asset, "material", name="board", rgba="0.36 0.45 0.55 1", specular="0.2")
    element(asset, "material", name="peg", rgba="0.95 0.55 0.15 1", specular="0.4")
    root.insert(3, asset)

    worldbody = root.find("worldbody")
    element(worldbody, "light", name="top", pos="0.3 0 2.0", dir="0 0 -1", directional="true",
            diffuse="0.6 0.6 0.6", castshadow="false")  # fmt: skip
    table = ET.Element(
        "geom",
        name="table",
        type="plane",
        size="1.5 1.5 0.05",
        material="table",
        contype="2",
        conaffinity="1",
        condim="3",
        group="0",
        friction=_vec(TABLE_FRICTION, 0.005, 0.0001),
    )
    worldbody.insert(0, table)
    element(worldbody, "camera", name="birdseye", pos="0.35 0 1.3", xyaxes="0 -1 0 1 0 0", fovy=45)
    eye = (1.25, -0.95, 0.85)
    element(
        worldbody,
        "camera",
        name="overview",
        pos=_vec(*eye),
        xyaxes=_look_at_xyaxes(eye, (0.3, 0.05, 0.18)),
        fovy=45,
    )
    _add_board(worldbody, shape, size, scale)
    wrist3 = worldbody.find(f".//body[@name='{WRIST3_BODY}']")
    _add_peg(wrist3, asset, shape, size)

    sensor = ET.SubElement(root, "sensor")
    element(sensor, "force", name="ft_force", site="ft")
    element(sensor, "torque", name="ft_torque", site="ft")
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"
