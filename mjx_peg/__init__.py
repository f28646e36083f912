"""mjx-peg: compliant peg-in-hole insertion learned with MuJoCo, MJX and Brax PPO."""

from mjx_peg import signals as _signals

_signals.install_for_program()  # a program of this package takes Ctrl-C before any import

from mjx_peg.world import gl as _gl  # noqa: E402

# Before anything imports MuJoCo: an unusable MUJOCO_GL would make `import mujoco` fail.
_gl.choose_backend()
