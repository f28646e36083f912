"""The arm's rigid-body dynamics for a real UR5e: H(q), h(q, qd) and the gravity torque g(q).

The operational-space law (skill/osc.py, Eq. 14) needs H and h every period. A real UR5e does not
stream them, so `UR5eArm` takes them from a model:

    MujocoArmModel(shape, size)   the scene the policy was trained in (scenes/ur5e.xml + the peg
                                  at its nominal grasp): the same H and h as training
    ControllerArmModel(control)   the robot controller's own model through ur_rtde
                                  (getMassMatrix, getCoriolisAndCentrifugalTorques), checked for
                                  sanity on every call

`direct_torque` on the UR5e always adds the controller's gravity compensation (UR Script Manual,
direct_torque), so the adapter sends u - g(q): `gravity` is what the model says the controller
adds. MuJoCo is imported only by `MujocoArmModel`, so the runtime still imports without it.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np


class ArmModel(Protocol):
    """What `UR5eArm` needs of a dynamics model."""

    def dynamics(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(H (6, 6), h (6,)): the joint-space inertia and the bias torques the skill must supply
        on top of what the controller adds itself (`gravity`)."""

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """(6,) the gravity torque the controller adds to every direct-torque command."""


class ModelError(RuntimeError):
    """The dynamics model returned something no arm can have (one line says what)."""


def gravity_torque(model, data, dof_adr: np.ndarray, qpos_adr: np.ndarray, q) -> np.ndarray:
    """(6,) g(q) of a MuJoCo arm model: the bias torque at rest (mj_rne with qd = 0).

    Writes q and a zero velocity into `data` (a scratch MjData of `model`)."""
    import mujoco

    data.qpos[qpos_adr] = q
    data.qvel[:] = 0.0
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    mujoco.mj_comVel(model, data)
    out = np.zeros(model.nv)
    mujoco.mj_rne(model, data, 0, out)
    return out[dof_adr]


class MujocoArmModel:
    """H and h of the training scene for a peg of `shape` and `size` (m) at its nominal grasp.

    h is `scene.bias_torque` (Coriolis, centrifugal and gravity, less the joints' viscous
    damping), as the simulated arm and the engines give it, so `dynamics` on a reading equals
    what the simulated arm reports for the same q, qd."""

    def __init__(self, shape: str, size: float):
        import mujoco

        from mjx_peg.world import scene

        self.model = m = scene.load_model(shape, size)
        m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT  # H and h only
        self.data = mujoco.MjData(m)
        self.scratch = mujoco.MjData(m)
        self.ids = scene.scene_ids(m)
        self._mass = np.zeros((m.nv, m.nv))
        self._bias_torque = scene.bias_torque

    def dynamics(self, q, qd) -> tuple[np.ndarray, np.ndarray]:
        import mujoco

        m, d, ids = self.model, self.data, self.ids
        d.qpos[ids.qpos_adr] = q
        d.qvel[ids.dof_adr] = qd
        mujoco.mj_fwdPosition(m, d)
        mujoco.mj_fwdVelocity(m, d)
        mujoco.mj_fullM(m, d, self._mass)
        dof = ids.dof_adr
        return (
            self._mass[np.ix_(dof, dof)].copy(),
            self._bias_torque(d.qfrc_bias, d.qfrc_passive, dof),
        )

    def gravity(self, q) -> np.ndarray:
        return gravity_torque(self.model, self.scratch, self.ids.dof_adr, self.ids.qpos_adr, q)


class ControllerArmModel:
    """H and the Coriolis/centrifugal torques from the UR controller, through an
    `RTDEControlInterface`; gravity is the controller's own, so h excludes it and `gravity` is
    zero. Every answer is checked: finite, H symmetric positive definite with a diagonal in
    [1e-3, 50] kg m^2 (the UR5e's link inertias seen from its joints), |h| < 100 N m; ur_rtde's
    issues report versions where these calls return zeros or garbage."""

    def __init__(self, control):
        self.control = control

    def dynamics(self, q, qd) -> tuple[np.ndarray, np.ndarray]:
        q, qd = [float(v) for v in q], [float(v) for v in qd]
        mass = np.asarray(self.control.getMassMatrix(q, True), dtype=np.float64)
        bias = np.asarray(self.control.getCoriolisAndCentrifugalTorques(q, qd), dtype=np.float64)
        if mass.size != 36 or bias.size != 6:
            raise ModelError(
                f"the controller's model returned {mass.size} inertia and {bias.size} bias "
                "numbers (expected 36 and 6)"
            )
        mass = mass.reshape(6, 6, order="F")  # ur_rtde returns H column by column
        check_inertia(mass)
        if not (np.all(np.isfinite(bias)) and np.abs(bias).max() < 100.0):
            raise ModelError(f"the controller's Coriolis torques are not sane: {bias.round(3)}")
        return mass, bias

    def gravity(self, q) -> np.ndarray:
        return np.zeros(6)


def check_inertia(mass: np.ndarray) -> None:
    """ModelError unless `mass` is a plausible UR5e joint-space inertia."""
    if not np.all(np.isfinite(mass)):
        raise ModelError("the joint-space inertia holds NaN or infinite values")
    if np.abs(mass - mass.T).max() > 1e-6 * max(1.0, np.abs(mass).max()):
        raise ModelError("the joint-space inertia is not symmetric")
    diag = np.diag(mass)
    if not (np.all(diag >= 1e-3) and np.all(diag <= 50.0)):
        raise ModelError(f"the joint-space inertia's diagonal {diag.round(4)} is not a UR5e's")
    if np.linalg.eigvalsh(mass).min() <= 0.0:
        raise ModelError("the joint-space inertia is not positive definite")
