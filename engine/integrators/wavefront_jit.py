"""engine/integrators/path_tracer.py's compaction of the surviving paths compiled with numba: their
next ray origins (the hit point moved off the surface, to the side they leave on), directions and
throughputs gathered in one loop, instead of nine gathers and the temporaries of the origin's
arithmetic.  The origin is the same float64 sum of the same products in the same order, so the same
bits (tests/integrators/test_wavefront_jit.py).  Imported only through engine/core/backend.py's
choice (it imports numba)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _next_rays(keep, point, side, offset, facing, new_d, beta):
    k = keep.shape[0]
    o = np.empty((3, k))
    d = np.empty((3, k))
    b = np.empty((3, k))
    for j in range(k):
        i = keep[j]
        s = side[i] * offset[i]
        for c in range(3):
            o[c, j] = point[c, i] + s * facing[c, i]
            d[c, j] = new_d[c, i]
            b[c, j] = beta[c, i]
    return o, d, b


def next_rays(keep, point, side, offset, facing, new_d, beta):
    """(o, d, beta) of the paths `keep`: point + (side x offset) facing, new_d and beta at keep (rows)."""
    rows = [np.ascontiguousarray(a, np.float64) for a in (point, facing, new_d, beta)]
    return _next_rays(np.ascontiguousarray(keep, np.int64), rows[0], np.ascontiguousarray(side, np.float64),
                      np.ascontiguousarray(offset, np.float64), rows[1], rows[2], rows[3])


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes."""
    rows = np.ones((3, 3))
    next_rays(np.array([0, 2]), rows, np.ones(3), np.ones(3), rows, rows, rows)
