"""mjx-peg: compliant peg-in-hole insertion learned with MuJoCo, MJX and Brax PPO."""

from mjx_peg.world import gl as _gl

# Before anything imports MuJoCo: an unusable MUJOCO_GL would make `import mujoco` fail.
_gl.choose_backend()
