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
def _ray_t(o, d, i, center, radius, j, t_best, bounded):
    """t of ray i with sphere j (inf: no hit, or not nearer than t_best where bounded)."""
    r = radius[j]
    fx, fy, fz = o[0, i] - center[0, j], o[1, i] - center[1, j], o[2, i] - center[2, j]
    d0, d1, d2 = d[0, i], d[1, i], d[2, i]
    half_b = fx * d0 + fy * d1 + fz * d2
    c = fx * fx + fy * fy + fz * fz - r * r
    if not (half_b * half_b - c) >= -1e-6 * r * r:
        return np.inf
    if not ((c <= 0.0) or (half_b <= 0.0)):
        return np.inf
    if bounded and not (-half_b - r) < t_best:
        return np.inf
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
        return t
    return np.inf


@jit
def _intersect(o, d, center, radius, t_best, bounded):
    """t of each ray i with sphere j = i (center (3, N), radius (N,)) or j = 0 (one sphere)."""
    n = o.shape[1]
    each = radius.shape[0] > 1
    t_out = np.full(n, np.inf)
    for i in range(n):
        t_out[i] = _ray_t(o, d, i, center, radius, i if each else 0, t_best[i] if bounded else 0.0, bounded)
    return t_out


@jit
def _pretest_constants(radius):
    """r * r and the pre-test's margin -1e-6 * r * r of every sphere: _ray_t's own products."""
    rr, margin = np.empty(radius.shape[0]), np.empty(radius.shape[0])
    for k in range(radius.shape[0]):
        r = radius[k]
        rr[k] = r * r
        margin[k] = -1e-6 * r * r
    return rr, margin


@nb.njit(cache=True, error_model="numpy", nogil=True, inline="always")
def _candidates(o, d, i, center, rr, margin, maybe):
    """_ray_t's two cheap pre-tests of ray i against every sphere at once, into maybe[k] (False: _ray_t
    returns inf); True if any passed.  The same float64 operations, evaluated without branches so the
    loop over the spheres runs in SIMD lanes: most (ray, sphere) pairs end here (docs/performance.md
    "Analytic spheres")."""
    ox, oy, oz = o[0, i], o[1, i], o[2, i]
    d0, d1, d2 = d[0, i], d[1, i], d[2, i]
    some = False
    for k in range(rr.shape[0]):
        fx, fy, fz = ox - center[0, k], oy - center[1, k], oz - center[2, k]
        half_b = fx * d0 + fy * d1 + fz * d2
        c = fx * fx + fy * fy + fz * fz - rr[k]
        m = ((half_b * half_b - c) >= margin[k]) & ((c <= 0.0) | (half_b <= 0.0))
        maybe[k] = m
        some |= m
    return some


@jit
def _nearest(o, d, center, radius, t, kind, prim, kind_id):
    """Every sphere against every ray, one after the other as engine/geometry/scene_geometry.py
    SceneGeometry._nearest folds them (bounded by the nearest t so far; nearer replaces, so of
    equal distances the lowest number wins): t updated in place, kind and prim where a sphere won.
    Only the spheres that pass the pre-tests (_candidates) go through _ray_t, in the same order."""
    rr, margin = _pretest_constants(radius)
    maybe = np.empty(radius.shape[0], np.bool_)
    for i in range(o.shape[1]):
        if not _candidates(o, d, i, center, rr, margin, maybe):
            continue
        best = t[i]
        for k in range(radius.shape[0]):
            if maybe[k]:
                tk = _ray_t(o, d, i, center, radius, k, best, True)
                if tk < best:
                    best = tk
                    kind[i] = kind_id
                    prim[i] = k
        t[i] = best


@jit
def _occluded(o, d, center, radius, tmax, hit):
    """hit[i] |= some sphere is met before tmax[i] (each tested bounded by tmax, as the NumPy loop;
    only the spheres that pass the pre-tests, _candidates)."""
    rr, margin = _pretest_constants(radius)
    maybe = np.empty(radius.shape[0], np.bool_)
    for i in range(o.shape[1]):
        if hit[i] or not _candidates(o, d, i, center, rr, margin, maybe):
            continue
        for k in range(radius.shape[0]):
            if maybe[k] and _ray_t(o, d, i, center, radius, k, tmax[i], True) < tmax[i]:
                hit[i] = True
                break


NO_BOUND = np.zeros(0)


def intersect_sphere(o, d, center, radius, t_best=None):
    """As spheres.intersect_sphere (one sphere: center (3,), radius a number; or one per ray)."""
    center = np.ascontiguousarray(np.asarray(center, np.float64).reshape(3, -1))
    radius = np.ascontiguousarray(np.asarray(radius, np.float64).reshape(-1))
    bounded = t_best is not None
    return _intersect(np.ascontiguousarray(o, np.float64), np.ascontiguousarray(d, np.float64), center, radius,
                      np.ascontiguousarray(t_best, np.float64) if bounded else NO_BOUND, bounded)


def nearest_spheres(o, d, center, radius, t, kind, prim, kind_id):
    """The nearest of all spheres (center (3, S), radius (S,)) folded into t (returned, a new
    array) and kind, prim (in place), as SceneGeometry._nearest's loop over them: the same t."""
    t = np.array(t, dtype=np.float64)              # a copy: the caller's array stays
    k, p = np.ascontiguousarray(kind, np.int8), np.ascontiguousarray(prim, np.int64)   # the compiled types
    _nearest(np.ascontiguousarray(o, np.float64), np.ascontiguousarray(d, np.float64),
             np.ascontiguousarray(center, np.float64), np.ascontiguousarray(radius, np.float64), t, k, p, kind_id)
    if k is not kind:
        kind[...] = k
    if p is not prim:
        prim[...] = p
    return t


def occluded_by_spheres(o, d, center, radius, tmax, hit):
    """hit |= any sphere met before tmax, in place (bool (N,), C-contiguous)."""
    _occluded(np.ascontiguousarray(o, np.float64), np.ascontiguousarray(d, np.float64),
              np.ascontiguousarray(center, np.float64), np.ascontiguousarray(radius, np.float64),
              np.ascontiguousarray(tmax, np.float64), hit)


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes."""
    o, d = np.zeros((3, 2)), np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]])
    intersect_sphere(o, d, np.array([0.0, 0.0, 3.0]), 1.0, np.full(2, np.inf))
    intersect_sphere(o, d, np.array([[0.0, 0.0], [0.0, 0.0], [3.0, 3.0]]), np.ones(2))
    centers, radii = np.array([[0.0, 0.0], [0.0, 0.0], [3.0, 6.0]]), np.ones(2)
    nearest_spheres(o, d, centers, radii, np.full(2, np.inf), np.zeros(2, np.int8), np.full(2, -1, np.int64), 2)
    occluded_by_spheres(o, d, centers, radii, np.full(2, 10.0), np.zeros(2, dtype=bool))
