"""engine/geometry/shapes/spheres.py `intersect_sphere` compiled with numba: one loop over the rays
and no temporaries.  The same float64 operations in the same order (the cheap pre-test, then the
stable solve), so the same t bit for bit (tests/geometry/test_spheres_jit.py).  Imported only
through engine/core/backend.py's choice (it imports numba)."""
from __future__ import annotations

import numpy as np

from ...core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _min(a, b):
    """np.minimum of two scalars (NaN wins)."""
    if a != a or b != b:
        return np.nan
    return a if a <= b else b


@jit
def _max(a, b):
    if a != a or b != b:
        return np.nan
    return a if a >= b else b


@jit
def _intersect(o, d, center, radius, t_best, bounded):
    """t of each ray i with sphere j = i (center (3, N), radius (N,)) or j = 0 (one sphere)."""
    n = o.shape[1]
    each = radius.shape[0] > 1
    t_out = np.full(n, np.inf)
    for i in range(n):
        j = i if each else 0
        r = radius[j]
        fx, fy, fz = o[0, i] - center[0, j], o[1, i] - center[1, j], o[2, i] - center[2, j]
        d0, d1, d2 = d[0, i], d[1, i], d[2, i]
        half_b = fx * d0 + fy * d1 + fz * d2
        c = fx * fx + fy * fy + fz * fz - r * r
        if not (half_b * half_b - c) >= -1e-6 * r * r:
            continue
        if not ((c <= 0.0) or (half_b <= 0.0)):
            continue
        if bounded and not (-half_b - r) < t_best[i]:
            continue
        a = d0 * d0 + d1 * d1 + d2 * d2
        b = 2.0 * half_b
        s = 0.5 * b / a
        v0, v1, v2 = fx - s * d0, fy - s * d1, fz - s * d2
        length = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        discriminant = 4.0 * a * (r + length) * (r - length)
        root = np.sqrt(_max(discriminant, 0.0))
        q = -0.5 * (b + np.copysign(root, b))
        t0 = q / a
        t1 = c / q
        near, far = _min(t0, t1), _max(t0, t1)
        t = near if near > 0.0 else far
        if discriminant >= 0.0 and t > 0.0 and np.isfinite(t):
            t_out[i] = t
    return t_out


NO_BOUND = np.zeros(0)


def intersect_sphere(o, d, center, radius, t_best=None):
    """As spheres.intersect_sphere (one sphere: center (3,), radius a number; or one per ray)."""
    center = np.ascontiguousarray(np.asarray(center, np.float64).reshape(3, -1))
    radius = np.ascontiguousarray(np.asarray(radius, np.float64).reshape(-1))
    bounded = t_best is not None
    return _intersect(np.ascontiguousarray(o, np.float64), np.ascontiguousarray(d, np.float64), center, radius,
                      np.ascontiguousarray(t_best, np.float64) if bounded else NO_BOUND, bounded)


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes."""
    o, d = np.zeros((3, 2)), np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]])
    intersect_sphere(o, d, np.array([0.0, 0.0, 3.0]), 1.0, np.full(2, np.inf))
    intersect_sphere(o, d, np.array([[0.0, 0.0], [0.0, 0.0], [3.0, 3.0]]), np.ones(2))
