"""engine/geometry/shapes/quads.py's quad test (Lagae and Dutre) compiled with numba: one loop over
the rays, each with one quad or its own, no temporaries; and all quads against each ray in one loop
(the nearest hit, a shadow ray's block) as engine/geometry/scene_geometry.py folds them quad by quad.
The same float64 operations in the same order (plane distance, the circumscribed-circle test, then the two triangles), so the same t bit for
bit (tests/geometry/test_quads_jit.py).  Imported only through engine/core/backend.py's choice."""
from __future__ import annotations

import numpy as np

from ...core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _ray_t(o, d, i, v00, v10, v11, v01, nrm, center, radius2, k, t_best, bounded):
    """t of ray i with quad k (rows (3, K)), +inf where it misses or, bounded, is not below t_best."""
    n0, n1, n2 = nrm[0, k], nrm[1, k], nrm[2, k]
    o0, o1, o2, d0, d1, d2 = o[0, i], o[1, i], o[2, i], d[0, i], d[1, i], d[2, i]
    a0, a1, a2 = v00[0, k], v00[1, k], v00[2, k]
    t = ((a0 * n0 + a1 * n1 + a2 * n2) - (n0 * o0 + n1 * o1 + n2 * o2)) / (n0 * d0 + n1 * d1 + n2 * d2)
    if not (t > 0.0 and np.isfinite(t)):
        return np.inf
    if bounded and not t < t_best:
        return np.inf
    r0 = o0 + t * d0 - center[0, k]
    r1 = o1 + t * d1 - center[1, k]
    r2 = o2 + t * d2 - center[2, k]
    if not (r0 * r0 + r1 * r1 + r2 * r2) <= radius2[k]:
        return np.inf
    return _edge_test(o0, o1, o2, d0, d1, d2, a0, a1, a2, v10, v11, v01, k, t)


@jit
def _edge_test(o0, o1, o2, d0, d1, d2, a0, a1, a2, v10, v11, v01, k, t):
    """t where the ray (o, d) meets quad k (corner a = v00) inside its edges, else +inf: the two
    triangles of Lagae and Dutre.  A function of its own: inlined into _ray_t, its arithmetic was
    computed for every ray, also those that the plane and circle tests had already sent away
    (1.0 -> 0.25 ms per quad for 32k rays, 2 % of them past the circle)."""
    e01_0, e01_1, e01_2 = v10[0, k] - a0, v10[1, k] - a1, v10[2, k] - a2
    e03_0, e03_1, e03_2 = v01[0, k] - a0, v01[1, k] - a1, v01[2, k] - a2
    p0, p1, p2 = d1 * e03_2 - d2 * e03_1, d2 * e03_0 - d0 * e03_2, d0 * e03_1 - d1 * e03_0
    det = p0 * e01_0 + p1 * e01_1 + p2 * e01_2
    inv = 1.0 / det
    s0, s1, s2 = o0 - a0, o1 - a1, o2 - a2
    alpha = (s0 * p0 + s1 * p1 + s2 * p2) * inv
    q0, q1, q2 = s1 * e01_2 - s2 * e01_1, s2 * e01_0 - s0 * e01_2, s0 * e01_1 - s1 * e01_0
    beta = (d0 * q0 + d1 * q1 + d2 * q2) * inv
    inside = alpha >= 0.0 and beta >= 0.0 and det != 0.0 and np.isfinite(det)
    if inside and alpha + beta > 1.0:
        b0, b1, b2 = v11[0, k], v11[1, k], v11[2, k]
        e23_0, e23_1, e23_2 = v01[0, k] - b0, v01[1, k] - b1, v01[2, k] - b2
        e21_0, e21_1, e21_2 = v10[0, k] - b0, v10[1, k] - b1, v10[2, k] - b2
        p0, p1, p2 = d1 * e21_2 - d2 * e21_1, d2 * e21_0 - d0 * e21_2, d0 * e21_1 - d1 * e21_0
        inv2 = 1.0 / (p0 * e23_0 + p1 * e23_1 + p2 * e23_2)
        s0, s1, s2 = o0 - b0, o1 - b1, o2 - b2
        alpha2 = (s0 * p0 + s1 * p1 + s2 * p2) * inv2
        q0, q1, q2 = s1 * e23_2 - s2 * e23_1, s2 * e23_0 - s0 * e23_2, s0 * e23_1 - s1 * e23_0
        beta2 = (d0 * q0 + d1 * q1 + d2 * q2) * inv2
        inside = alpha2 >= 0.0 and beta2 >= 0.0
    return t if inside else np.inf


@jit
def _intersect(o, d, v00, v10, v11, v01, nrm, center, radius2, single, prim, t_best, bounded):
    """t of each ray i with quad `single` (>= 0) or with quad prim[i]; quads as rows (3, K)."""
    m = o.shape[1]
    t_out = np.full(m, np.inf)
    for i in range(m):
        k = single if single >= 0 else prim[i]
        bound = t_best[i] if bounded else np.inf
        t_out[i] = _ray_t(o, d, i, v00, v10, v11, v01, nrm, center, radius2, k, bound, bounded)
    return t_out


@jit
def _nearest(o, d, v00, v10, v11, v01, nrm, center, radius2, t, kind, prim, kind_id):
    """Every quad against every ray, one after the other as engine/geometry/scene_geometry.py
    SceneGeometry._nearest folds them (bounded by the nearest t so far; nearer replaces, so of equal
    distances the lowest number wins): t, kind and prim updated in place."""
    for i in range(o.shape[1]):
        best = t[i]
        for k in range(radius2.shape[0]):
            tk = _ray_t(o, d, i, v00, v10, v11, v01, nrm, center, radius2, k, best, True)
            if tk < best:
                best = tk
                kind[i] = kind_id
                prim[i] = k
        t[i] = best


@jit
def _occluded(o, d, v00, v10, v11, v01, nrm, center, radius2, tmax, hit):
    """hit[i] |= some quad is met before tmax[i] (each tested bounded by tmax, as the NumPy loop)."""
    for i in range(o.shape[1]):
        if hit[i]:
            continue
        for k in range(radius2.shape[0]):
            if _ray_t(o, d, i, v00, v10, v11, v01, nrm, center, radius2, k, tmax[i], True) < tmax[i]:
                hit[i] = True
                break


NO_PRIM, NO_BOUND = np.zeros(0, np.int64), np.zeros(0)


def intersect(quads, single, prim, o, d, t_best):
    """QuadSet's test: quad `single` (an int) for every ray, or prim[i] for ray i (single = -1)."""
    v00, v10, v11, v01, n, center = quads.vector_rows
    bounded = t_best is not None
    return _intersect(np.ascontiguousarray(o, np.float64), np.ascontiguousarray(d, np.float64), v00, v10, v11, v01,
                      n, center, quads.radius2, int(single),
                      NO_PRIM if prim is None else np.ascontiguousarray(prim, np.int64),
                      np.ascontiguousarray(t_best, np.float64) if bounded else NO_BOUND, bounded)


def nearest_quads(quads, o, d, t, kind, prim, kind_id):
    """The nearest of all quads folded into t (returned, a new array) and kind (int8), prim (int64) in
    place, as SceneGeometry._nearest's loop over them: the same t."""
    t = np.array(t, dtype=np.float64)              # a copy: the caller's array stays
    k, p = np.ascontiguousarray(kind, np.int8), np.ascontiguousarray(prim, np.int64)   # the compiled types
    _nearest(np.ascontiguousarray(o, np.float64), np.ascontiguousarray(d, np.float64), *quads.vector_rows,
             quads.radius2, t, k, p, kind_id)
    if k is not kind:
        kind[...] = k
    if p is not prim:
        prim[...] = p
    return t


def occluded_by_quads(quads, o, d, tmax, hit):
    """hit |= any quad met before tmax, in place (bool (N,), C-contiguous)."""
    _occluded(np.ascontiguousarray(o, np.float64), np.ascontiguousarray(d, np.float64), *quads.vector_rows,
              quads.radius2, np.ascontiguousarray(tmax, np.float64), hit)


class _OneQuad:
    """The tables QuadSet would hold for one quad in the plane z = 2 (warm-up data)."""
    def __init__(self):
        corners = np.array([[-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [1.0, 1.0, 2.0], [-1.0, 1.0, 2.0]])
        self.vector_rows = [np.ascontiguousarray(c[:, None]) for c in corners] + [np.array([[0.0], [0.0], [1.0]]),
                                                                               np.array([[0.0], [0.0], [2.0]])]
        self.radius2 = np.array([2.0])


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes."""
    quads = _OneQuad()
    o, d = np.zeros((3, 2)), np.array([[0.0, 0.9], [0.0, 0.9], [1.0, 1.0]])
    intersect(quads, 0, None, o, d, None)
    intersect(quads, -1, np.zeros(2, np.int64), o, d, np.full(2, np.inf))
    nearest_quads(quads, o, d, np.full(2, np.inf), np.zeros(2, np.int8), np.full(2, -1, np.int64), 3)
    occluded_by_quads(quads, o, d, np.full(2, 10.0), np.zeros(2, dtype=bool))
