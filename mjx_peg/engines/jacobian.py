"""The tcp Jacobian and its derivative from MuJoCo's bound fields, batched; and the index that
expands MjData.M (the sparse lower triangle of the mass matrix) to dense (mj_fullM).

`jacobians` is MuJoCo's mj_jac and mj_jacDot, operation for operation (so that the bits match),
over many simulations at once, written over the array-API namespace of its inputs: NumPy in the
CPU engine's NumPy pass, XLA in its compiled one (`engines/compiled.py`).
"""

from __future__ import annotations

import mujoco
import numpy as np

from mjx_peg.array_api import namespace_of


def _cross(a, b):
    """(3, ...) a x b of vectors along the first axis (component-major, so that NumPy runs long
    loops), each component computed as MuJoCo's mju_cross so that the bits match:
    (a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0)."""
    xp = namespace_of(a, b)
    return xp.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])  # fmt: skip


def jacobians(cdof, cdof_dot, cvel, com, point):
    """jac, jac_dot (n, 6, nv): [linear; angular] Jacobian of world `point` (n, 3) on a body whose
    dof chain is every dof, and its time derivative: MuJoCo's mj_jac and mj_jacDot, operation for
    operation.

    cdof, cdof_dot: (n, nv, 6) dof motion axes and their derivatives, [angular, linear] about
    `com` (n, 3), the subtree centre of mass of the body's root; cvel: (n, 6) the body's velocity
    in the same form.
    """
    xp = namespace_of(cdof, cdof_dot, cvel, com, point)
    axes = xp.permute_dims(cdof, (2, 0, 1))  # (6, n, nv)
    axes_dot = xp.permute_dims(cdof_dot, (2, 0, 1))
    offset = xp.permute_dims(point - com, (1, 0))  # (3, n)
    vel = xp.permute_dims(cvel, (1, 0))
    point_vel = vel[3:] - _cross(offset, vel[:3])  # mju_transformSpatial
    offset, point_vel = offset[:, :, None], point_vel[:, :, None]  # (3, n, 1): over the dofs
    jac = xp.concat([axes[3:] + _cross(axes[:3], offset), axes[:3]])
    jac_dot = xp.concat(
        [(axes_dot[3:] + _cross(axes_dot[:3], offset)) + _cross(axes[:3], point_vel), axes_dot[:3]]
    )
    return xp.permute_dims(jac, (1, 0, 2)), xp.permute_dims(jac_dot, (1, 0, 2))


def dense_mass_index(m: mujoco.MjModel) -> np.ndarray:
    """(nv * nv,) index into MjData.M (the sparse lower triangle) of each dense entry."""
    index = np.full((m.nv, m.nv), -1)
    for row in range(m.nv):
        for adr in range(m.M_rowadr[row], m.M_rowadr[row] + m.M_rownnz[row]):
            col = m.M_colind[adr]
            index[row, col] = index[col, row] = adr
    assert (index >= 0).all(), "the arm's mass matrix must be dense (one chain)"
    return index.ravel()


def chain_is_every_dof(m: mujoco.MjModel, body: int) -> bool:
    """Whether the dof chain of `body` (through its weld parent) is every dof of `m`."""
    body = m.body_weldid[body]
    dofs, i = [], m.body_dofadr[body] + m.body_dofnum[body] - 1
    while i >= 0:
        dofs.append(i)
        i = m.dof_parentid[i]
    return sorted(dofs) == list(range(m.nv))
