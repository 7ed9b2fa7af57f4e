"""Inputs of the compiled kernels (the `*_jit.py` twins) as contiguous read-only arrays.

numba compiles one version of a kernel per signature, and an array's signature includes whether it
is writable and contiguous.  Handing every input over read-only and contiguous makes one compiled
version (warm_up's, engine/core/backend.py) serve the callers' writable arrays, their read-only ones
(np.broadcast_to views) and their column slices, instead of a compilation in each worker's first
render (scripts/check_warm_up.py).  Used by the kernels of several layers, hence here."""
from __future__ import annotations

import numpy as np


def read_only(a: np.ndarray) -> np.ndarray:
    """a, or a read-only view of it (the data is not copied)."""
    if a.flags.writeable:
        a = a.view()
        a.flags.writeable = False
    return a


def contiguous(a, dtype=np.float64) -> np.ndarray:
    """a as a contiguous read-only array of `dtype` (copied only when it is not one)."""
    return read_only(np.ascontiguousarray(a, dtype))


def fitted(a, shape, dtype=np.float64) -> np.ndarray:
    """a as a contiguous read-only array of `shape` and `dtype` (np.broadcast_to only when needed: its
    Python costs more than the kernels' work on small batches)."""
    if isinstance(a, np.ndarray) and a.shape == shape:
        return contiguous(a, dtype)
    return contiguous(np.broadcast_to(a, shape), dtype)
