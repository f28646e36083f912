"""Every fixed number and name of the physical setup, in one place (CONVENTIONS.md).

Plain Python (no NumPy, no MuJoCo): the scene, the task sampler, the kinematics, the engines,
the policy's observation and the robot runtime all read these.
"""

from __future__ import annotations

import math

# Cross-sections, in TrialSpec.shape_id order; rotational symmetry order of each (0: a circle,
# whose yaw does not matter).
SHAPES: tuple[str, ...] = ("circle", "square", "triangle")
SIZES_MM: tuple[float, ...] = (25.0, 50.0, 60.0)  # the paper's sizes S (section 5)
SYMMETRY: tuple[int, ...] = (0, 4, 3)
HOLE_SCALE = {"circle": 1.03, "square": 1.08, "triangle": 1.08}  # hole size / peg size S
CIRCLE_SIDES = 16  # sides of the round peg's prism (circumradius D/2)
HOLE_SIDES = {"circle": 16, "square": 4, "triangle": 3}  # boxes (= polygon edges) of each hole

HOLE_DEPTH = 0.08  # m, board thickness (the hole runs through it)
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
