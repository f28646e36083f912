"""The array-API namespace of a computation's inputs, the one write the API lacks, and the small
batched products whose best form differs between NumPy and XLA.

The skill, the rotations and the trial's period are written once over the namespace of their
inputs (NumPy 2 or JAX, tracers included); this module imports neither numpy nor jax.

`matvec`, `matmul` and `solve_spd` are one operation with two forms: on NumPy the BLAS / LAPACK
call (`@`, `linalg.solve`: the reference's bits), on JAX elementwise products and sums over the
last axes. XLA on a CPU runs a batched `dot` or `linalg.solve` of (..., 6, 6) matrices as one
library call per matrix and a kernel of its own that nothing fuses with; the elementwise forms
fuse with their neighbours (design notes: docs/design/compiled_period.md).
"""

from __future__ import annotations

import importlib
import types


def namespace_of(*arrays) -> types.ModuleType:
    """Array-API namespace shared by `arrays` (a non-NumPy one wins; Python scalars are skipped).

    JAX arrays and tracers provide `__array_namespace__`; when NumPy and JAX arrays are mixed
    (e.g. fitted NumPy weights with a traced phase) the JAX namespace is returned so the result
    can be traced. With only Python scalars, NumPy is imported lazily.
    """
    found = None
    for a in arrays:
        getter = getattr(a, "__array_namespace__", None)
        if getter is not None:
            xp = getter()
        elif type(a).__module__.split(".")[0] in ("jax", "jaxlib"):
            xp = importlib.import_module("jax.numpy")
        else:
            continue
        if found is None or found.__name__ == "numpy":
            found = xp
    return found if found is not None else importlib.import_module("numpy")


def ring_write(ring, index, value, mask):
    """`ring` (..., W) with ring[..., index % W] = value where `mask` (index, value, mask: (...,)).

    NumPy (rings (n, W): the CPU engine's rows) writes the masked entries in place and returns
    the same array (a trial's ring is 1 s of periods: copying it every period would cost more than
    the rest of the period); JAX returns a new array, one entry per ring scattered (XLA writes it
    in place where the ring's buffer is donated).
    """
    xp = namespace_of(ring, value)
    width = ring.shape[-1]
    if xp.__name__ == "numpy":
        if ring.ndim != 2:
            raise ValueError(f"ring_write on NumPy takes (n, W) rings, got {ring.shape}")
        rows = xp.nonzero(mask)[0]
        ring[rows, index[rows] % width] = value[rows]
        return ring
    # JAX: a scatter of one entry per ring (updated in place where the caller donates the ring)
    flat = xp.reshape(ring, (-1, width))
    rows = xp.arange(flat.shape[0])
    at = xp.reshape(index % width, (-1,))
    old = flat[rows, at]
    new = xp.where(xp.reshape(mask, (-1,)), xp.reshape(value, (-1,)), old)
    return xp.reshape(flat.at[rows, at].set(new), ring.shape)


def _is_numpy(xp) -> bool:
    return xp.__name__ == "numpy"


def matvec(mat, vec):
    """(..., m) mat (..., m, n) @ vec (..., n)."""
    xp = namespace_of(mat, vec)
    if _is_numpy(xp):
        return (mat @ vec[..., None])[..., 0]
    return xp.sum(mat * vec[..., None, :], axis=-1)


def matmul(a, b):
    """(..., m, k) a (..., m, n) @ b (..., n, k)."""
    xp = namespace_of(a, b)
    if _is_numpy(xp):
        return a @ b
    return xp.sum(a[..., :, :, None] * b[..., None, :, :], axis=-2)


def solve_spd(a, b):
    """(..., n) x with a x = b, a (..., n, n) symmetric positive definite, b (..., n).

    NumPy: LAPACK's LU (`linalg.solve`). JAX: Cholesky, a = L L^T, unrolled over the n (small,
    static) rows, elementwise over the batch; it reads the lower triangle of a only.
    """
    xp = namespace_of(a, b)
    if _is_numpy(xp):
        return xp.linalg.solve(a, b[..., None])[..., 0]
    n = a.shape[-1]
    low = [[None] * n for _ in range(n)]  # L[i][j], j <= i, each (...,)
    for j in range(n):
        diag = a[..., j, j]
        for k in range(j):
            diag = diag - low[j][k] * low[j][k]
        low[j][j] = xp.sqrt(diag)
        for i in range(j + 1, n):
            entry = a[..., i, j]
            for k in range(j):
                entry = entry - low[i][k] * low[j][k]
            low[i][j] = entry / low[j][j]
    y = [None] * n  # L y = b
    for i in range(n):
        entry = b[..., i]
        for k in range(i):
            entry = entry - low[i][k] * y[k]
        y[i] = entry / low[i][i]
    x = [None] * n  # L^T x = y
    for i in reversed(range(n)):
        entry = y[i]
        for k in range(i + 1, n):
            entry = entry - low[k][i] * x[k]
        x[i] = entry / low[i][i]
    return xp.stack(x, axis=-1)


def tree_map(f, tree, *rest):
    """f over the leaves of NamedTuples of arrays (nested), like `jax.tree.map` for this
    package's state tuples without importing JAX; `rest` are trees of the same structure. None
    is an empty subtree, as in JAX (an optional field left out)."""
    if tree is None:
        return None
    if isinstance(tree, tuple) and hasattr(tree, "_fields"):
        return type(tree)(*(tree_map(f, *parts) for parts in zip(tree, *rest, strict=True)))
    return f(tree, *rest)
