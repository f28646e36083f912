"""What the skill needs from an arm each control period, and what it sends back.

An `Arm` is anything with `period`, `read()`, `send(torque)` and `hold()`. A real UR5e adapter
computes the tcp kinematics from `mjx_peg.world.kinematics` (DH model + tool length) and takes the
joint-space inertia H and bias h from the robot's model; the simulated arm (`sim_arm.py`) takes
all of it from MuJoCo.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np


class ArmState(NamedTuple):
    """One control period's measurements; world (= base) frame, SI units, NumPy float64."""

    t: float  # s since the arm was set up (the skill's clock starts at the first read)
    q: np.ndarray  # (6,) joint positions
    qd: np.ndarray  # (6,) joint velocities
    tcp_pos: np.ndarray  # (3,) nominal peg tip (tcp)
    tcp_rot: np.ndarray  # (3, 3) tcp orientation
    jac: np.ndarray  # (6, 6) tcp Jacobian, linear rows then angular
    jac_dot: np.ndarray  # (6, 6) time derivative of `jac`
    mass: np.ndarray  # (6, 6) joint-space inertia H
    bias: np.ndarray  # (6,) h: Coriolis, centrifugal and gravity torques (and joint damping)
    force: np.ndarray  # (3,) F/T force, sensor frame: the load the flange exerts on the peg
    torque: np.ndarray  # (3,) F/T moment, same frame and sense
    ft_pos: np.ndarray  # (3,) F/T sensor position
    ft_rot: np.ndarray  # (3, 3) F/T sensor orientation


class Arm(Protocol):
    """The interface the runtime drives; `period` is the time between two commands (s)."""

    period: float

    def read(self) -> ArmState:
        """Measure; blocks until the next command is due."""

    def send(self, torque: np.ndarray) -> None:
        """Command joint torques (6,) N m, held until the next `send`."""

    def hold(self) -> None:
        """Stop commanding the skill: hold still (gravity compensation) or protective-stop."""
