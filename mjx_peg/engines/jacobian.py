"""The tcp Jacobian and its derivative from MuJoCo's bound fields, batched in NumPy.

MuJoCo's mj_jac and mj_jacDot, operation for operation (so that the bits match), over many
simulations at once; and the index that expands MjData.M (the sparse lower triangle of the
mass matrix) to dense (mj_fullM).
"""

from __future__ import annotations

import mujoco
import numpy as np

_NEXT, _LAST = np.array([1, 2, 0]), np.array([2, 0, 1])


def _cross(a, b):
    """(3, ...) a x b of vectors along the first axis (component-major, so that NumPy runs long
    loops), each component computed as MuJoCo's mju_cross so that the bits match:
    (a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0)."""
    return a[_NEXT] * b[_LAST] - a[_LAST] * b[_NEXT]


def jacobians(cdof, cdof_dot, cvel, com, point):
    """jac, jac_dot (n, 6, nv): [linear; angular] Jacobian of world `point` (n, 3) on a body whose
    dof chain is every dof, and its time derivative: MuJoCo's mj_jac and mj_jacDot, operation for
    operation.

    cdof, cdof_dot: (n, nv, 6) dof motion axes and their derivatives, [angular, linear] about
    `com` (n, 3), the subtree centre of mass of the body's root; cvel: (n, 6) the body's velocity
    in the same form.
    """
    n, nv = cdof.shape[:2]
    axes = np.ascontiguousarray(cdof.transpose(2, 0, 1))  # (6, n, nv)
    axes_dot = np.ascontiguousarray(cdof_dot.transpose(2, 0, 1))
    offset = np.ascontiguousarray((point - com).T)  # (3, n)
    vel = np.ascontiguousarray(cvel.T)
    point_vel = vel[3:] - _cross(offset, vel[:3])  # mju_transformSpatial
    offset = np.repeat(offset[:, :, None], nv, axis=2)  # (3, n, nv)
    point_vel = np.repeat(point_vel[:, :, None], nv, axis=2)
    jac, jac_dot = np.empty((6, n, nv)), np.empty((6, n, nv))
    np.add(axes[3:], _cross(axes[:3], offset), out=jac[:3])
    jac[3:] = axes[:3]
    np.add(axes_dot[3:], _cross(axes_dot[:3], offset), out=jac_dot[:3])
    jac_dot[:3] += _cross(axes[:3], point_vel)
    jac_dot[3:] = axes_dot[:3]
    return (
        np.ascontiguousarray(jac.transpose(1, 0, 2)),
        np.ascontiguousarray(jac_dot.transpose(1, 0, 2)),
    )


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
