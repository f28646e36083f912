"""The array-API namespace of a computation's inputs, and the one write the API lacks.

The skill, the rotations and the trial's period are written once over the namespace of their
inputs (NumPy 2 or JAX, tracers included); this module imports neither numpy nor jax.
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
    the same array (a trial's ring is
    1 s of periods: copying it every period would cost more than the rest of the period); JAX,
    which has no in-place write, returns a new array.
    """
    xp = namespace_of(ring, value)
    width = ring.shape[-1]
    if xp.__name__ == "numpy":
        if ring.ndim != 2:
            raise ValueError(f"ring_write on NumPy takes (n, W) rings, got {ring.shape}")
        rows = xp.nonzero(mask)[0]
        ring[rows, index[rows] % width] = value[rows]
        return ring
    hit = (xp.arange(width) == (index % width)[..., None]) & mask[..., None]
    return xp.where(hit, value[..., None], ring)


def tree_map(f, tree, *rest):
    """f over the leaves of NamedTuples of arrays (nested), like `jax.tree.map` for this
    package's state tuples without importing JAX; `rest` are trees of the same structure. None
    is an empty subtree, as in JAX (an optional field left out)."""
    if tree is None:
        return None
    if isinstance(tree, tuple) and hasattr(tree, "_fields"):
        return type(tree)(*(tree_map(f, *parts) for parts in zip(tree, *rest, strict=True)))
    return f(tree, *rest)
