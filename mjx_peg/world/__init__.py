"""The world: the UR5e, the board and the peg, and the trials drawn in it (CONVENTIONS.md).

constants.py    every fixed number and name of the physical setup
rotations.py    rotation matrices, quaternions, rotation vectors
kinematics.py   the UR5e's closed-form forward and inverse kinematics
parts.py        the family of parts: what S measures, the hole's clearances (fits, ranges), walls
mjcf.py         the scene's MJCF for one part (shape, size, hole scale)
scene.py        the compiled scene and the fields each trial overwrites
pose_solver.py  a site put at a pose by damped least squares (rendering, tests)
task.py         TaskConfig -> TrialSpec: boards, errors, frictions, start configurations
render.py, gl.py, mujoco_log.py   images, the GL back-end, MuJoCo's warnings
scene_cli.py    mjx-peg-scene: a scene's XML and picture
"""
