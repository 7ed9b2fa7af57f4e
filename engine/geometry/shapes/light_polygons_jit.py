"""engine/geometry/shapes/light_polygons.py's polygon test compiled with numba: one loop over the
rays, each with one Area light or its own, walking its corners.  The same float64 operations in
the same order (plane distance, then the edge tests of the convex polygon), so the same t bit for
bit (tests/geometry/test_light_polygons_jit.py).  Imported only through engine/core/backend.py's
choice (it imports numba)."""
from __future__ import annotations

import numpy as np

from ...core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _intersect(o, d, corners, size, nrm, single, prim, sees, t_best):
    """t of each ray i with light `single` (>= 0) or prim[i]; corners (width, 3, K) padded, size (K,);
    sees[i] False: ray i cannot see its light (+inf)."""
    m = o.shape[1]
    t_out = np.full(m, np.inf)
    for i in range(m):
        k = single if single >= 0 else prim[i]
        if sees.shape[0] and not sees[i]:
            continue
        n0, n1, n2 = nrm[0, k], nrm[1, k], nrm[2, k]
        o0, o1, o2, d0, d1, d2 = o[0, i], o[1, i], o[2, i], d[0, i], d[1, i], d[2, i]
        t = (((corners[0, 0, k] * n0 + corners[0, 1, k] * n1 + corners[0, 2, k] * n2)
              - (n0 * o0 + n1 * o1 + n2 * o2)) / (n0 * d0 + n1 * d1 + n2 * d2))
        if not (t > 0.0 and np.isfinite(t) and t < t_best[i]):
            continue
        p0, p1, p2 = o0 + t * d0, o1 + t * d1, o2 + t * d2
        inside = True
        s = size[k]
        for c in range(s):
            c1 = (c + 1) % s
            a0, a1, a2 = corners[c, 0, k], corners[c, 1, k], corners[c, 2, k]
            e0, e1, e2 = corners[c1, 0, k] - a0, corners[c1, 1, k] - a1, corners[c1, 2, k] - a2
            b0, b1, b2 = p0 - a0, p1 - a1, p2 - a2
            x0, x1, x2 = e1 * b2 - e2 * b1, e2 * b0 - e0 * b2, e0 * b1 - e1 * b0
            inside = inside and (x0 * n0 + x1 * n1 + x2 * n2) >= 0.0
        if inside:
            t_out[i] = t
    return t_out


NO_PRIM, NO_MASK = np.zeros(0, np.int64), np.zeros(0, np.bool_)


def intersect(lights, single, prim, sees, o, d, t_best):
    """LightPolygons' test: light `single` (an int) for every ray, or prim[i] for ray i (single = -1);
    sees: None, or per ray whether it can see its light."""
    return _intersect(np.ascontiguousarray(o, np.float64), np.ascontiguousarray(d, np.float64), lights.corner_rows,
                      lights.size, lights.normal_rows, int(single),
                      NO_PRIM if prim is None else np.ascontiguousarray(prim, np.int64),
                      NO_MASK if sees is None else np.ascontiguousarray(sees, np.bool_),
                      np.ascontiguousarray(t_best, np.float64))


class _OneSquare:
    """The tables LightPolygons would hold for one square in the plane z = 2 (warm-up data)."""
    def __init__(self):
        square = np.array([[-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [1.0, 1.0, 2.0], [-1.0, 1.0, 2.0]])
        self.corner_rows = np.ascontiguousarray(square[:, :, None])
        self.size = np.array([4], np.int64)
        self.normal_rows = np.array([[0.0], [0.0], [1.0]])


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes."""
    lights = _OneSquare()
    o, d = np.zeros((3, 2)), np.array([[0.0, 0.9], [0.0, 0.9], [1.0, 1.0]])
    intersect(lights, 0, None, None, o, d, np.full(2, np.inf))
    intersect(lights, -1, np.zeros(2, np.int64), np.ones(2, np.bool_), o, d, np.full(2, np.inf))
