"""Every fixed number and name of the physical setup, in one place (CONVENTIONS.md).

Plain Python (no NumPy, no MuJoCo): the scene, the task sampler, the kinematics, the engines,
the policy's observation and the robot runtime all read these.
"""

from __future__ import annotations

import math

# The family of parts: cross-sections in TrialSpec.shape_id order (the paper's three first, so
# their ids keep their meaning), each with its characteristic size S (m):
#   circle     diameter D
#   square     edge L
#   triangle   equilateral, edge L
#   hexagon    regular, width across flats (its inscribed circle is the circle's of D = S)
#   rectangle  2:1, long edge S, short edge S/2 (a keyed part)
# Every section then fits an S-by-S square but the hexagon's corners (1.15 S across), so S sizes
# the board, the camera's view and the arm's reach alike.
SHAPES: tuple[str, ...] = ("circle", "square", "triangle", "hexagon", "rectangle")
PAPER_SHAPES: tuple[str, ...] = SHAPES[:3]  # the paper's cross-sections (section 5)
SIZES_MM: tuple[float, ...] = (25.0, 50.0, 60.0)  # the paper's sizes S (section 5)
SIZE_RANGE: tuple[float, float] = (0.01, 0.08)  # m: the sizes S the family is built and tested at
TRAINING_SIZE = 0.05  # m: the paper's training size S, at which its error ranges are given
# Rotational symmetry order n of each section (0: a circle, whose yaw does not matter).
SYMMETRY: tuple[int, ...] = (0, 4, 3, 6, 2)
# The peg's inradius and circumradius over S (the round peg's are the circle's, D/2).
INRADIUS: dict[str, float] = {
    "circle": 0.5,
    "square": 0.5,
    "triangle": 0.5 / math.sqrt(3.0),
    "hexagon": 0.5,
    "rectangle": 0.25,
}
CIRCUMRADIUS: dict[str, float] = {
    "circle": 0.5,
    "square": math.sqrt(0.5),
    "triangle": 1.0 / math.sqrt(3.0),
    "hexagon": 1.0 / math.sqrt(3.0),
    "rectangle": math.sqrt(5.0) / 4.0,
}
# The hole's clearance, as the hole's size over the peg's (TrialSpec.hole_scale): the hole is the
# peg's section scaled by it about the axis (the circle's hole: a HOLE_SIDES-gon whose inscribed
# diameter is hole_scale D). The paper's fits (section 5): 1.03 D round, 1.08 L for a section with
# corners; the hexagon and the rectangle are sections with corners and take 1.08 too. Tight fits:
# a third of the paper's round clearance, a quarter of its polygonal one.
HOLE_SCALE: dict[str, float] = {
    "circle": 1.03,
    "square": 1.08,
    "triangle": 1.08,
    "hexagon": 1.08,
    "rectangle": 1.08,
}
TIGHT_HOLE_SCALE: dict[str, float] = {
    "circle": 1.01,
    "square": 1.02,
    "triangle": 1.02,
    "hexagon": 1.02,
    "rectangle": 1.02,
}
HOLE_FITS: dict[str, dict[str, float]] = {"paper": HOLE_SCALE, "tight": TIGHT_HOLE_SCALE}
HOLE_SCALE_RANGE: tuple[float, float] = (1.01, 1.25)  # the clearances a scene may be built with
# A range of clearances (TaskConfig.hole_scale) is drawn over evenly spaced values at most this
# far apart, so that the trials of a range share a few compiled scenes.
HOLE_SCALE_STEP = 0.005
CIRCLE_SIDES = 16  # sides of the round peg's prism (circumradius D/2)
# Walls (boxes) of each hole, one per polygon edge, their outward normals evenly spaced.
HOLE_SIDES = {"circle": 16, "square": 4, "triangle": 3, "hexagon": 6, "rectangle": 4}

HOLE_DEPTH = 0.08  # m, board thickness (the hole runs through it), the paper's for every part
PEG_LENGTH = 0.15  # m: 80 mm in the hole leaves the flange 70 mm above the board top
PEG_MASS = 0.3  # kg
GOAL_HEIGHT = 0.0  # m: the tcp's goal (and the goal configuration) is at the table top

# Where the grasp errors (dz, tilt_x, tilt_y) of a trial are applied (world/task.py): "board"
# raises and tilts the board about its hole's entrance centre (the paper, section 5.2: "errors in
# the board location and pose"); "flange" shifts and tilts the peg in the gripper, which moves its
# tip by PEG_LENGTH sin(tilt) before contact (ours, harder).
GRASP_MODELS: tuple[str, ...] = ("board", "flange")

SUCCESS_REWARD = 38000.0  # the paper's reward for a successful trial

TIMESTEP = 0.002  # s: physics step and control period (500 Hz)

# UR5e joints and motors, in order (CONVENTIONS.md).
ACTUATOR_NAMES: tuple[str, ...] = (
    "shoulder_pan",
    "shoulder_lift",
    "elbow",
    "wrist_1",
    "wrist_2",
    "wrist_3",
)
JOINT_NAMES: tuple[str, ...] = tuple(f"{name}_joint" for name in ACTUATOR_NAMES)
TORQUE_LIMITS: tuple[float, ...] = (150.0, 150.0, 150.0, 28.0, 28.0, 28.0)  # N m

# Elbow up, wrist down, facing +x: the flange at (0.49, 0.13, 0.49) m, tool z along world -z,
# tool x along world -y. The scene's keyframe, and the configuration IK branches are chosen by.
HOME_Q: tuple[float, ...] = (math.pi, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0)
