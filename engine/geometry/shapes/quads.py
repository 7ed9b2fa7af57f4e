"""Planar convex quadrilaterals by the test of Lagae and Dutre (report 2.2.2).

The quad V00, V10, V11, V01 is split along the diagonal V10-V01 into T = (V00, V10, V01)
and T' = (V11, V01, V10).  A ray is first tested against T with barycentric
coordinates alpha, beta (eq. 2.7-2.8); only when alpha + beta > 1 is T' tested, without
its own alpha' + beta' <= 1 check, so the diagonal can never open a crack (docs/hard-cases.md H8).
The distance t comes from the quad's plane, the same for both halves.
"""
from __future__ import annotations

import numpy as np

from ...core.vec import cross, dot, max_abs3, rows

EPS64 = np.finfo(np.float64).eps


class QuadSet:
    """All quads of a scene as arrays, for the vectorised test."""

    def __init__(self, corners: np.ndarray, backend: str = "numpy"):
        """backend (engine/core/backend.py): "numba" tests with the compiled twin
        (engine/geometry/shapes/quads_jit.py, the same t), "numpy" with `_intersect` below."""
        q = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 3)
        self.v00, self.v10, self.v11, self.v01 = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
        normal = np.cross(self.v10 - self.v00, self.v01 - self.v00)
        self.normal = normal / np.linalg.norm(normal, axis=1)[:, None]
        self.scale = np.abs(q).max(axis=(1, 2))
        # Circumscribed circle about the centroid: a cheap test before the edge tests.
        self.center = q.mean(axis=1)
        self.radius2 = (((q - self.center[:, None]) ** 2).sum(axis=2)).max(axis=1) * (1 + 1e-9)
        self.count = len(q)
        self.normal_rows, self.v00_rows = rows(self.normal), rows(self.v00)
        self.vector_rows = [rows(a) for a in (self.v00, self.v10, self.v11, self.v01, self.normal, self.center)]
        self.compiled = None
        self.loops = None       # compiled: (nearest, occluded) of all quads in one loop per ray
        if backend == "numba":
            from . import quads_jit
            self.compiled = quads_jit.intersect
            self.loops = quads_jit.nearest_quads, quads_jit.occluded_by_quads

    def intersect_one(self, k: int, o: np.ndarray, d: np.ndarray,
                      t_best: np.ndarray | None = None) -> np.ndarray:
        """t > 0 of each ray (rows, see engine/core/vec.py) with quad k, +inf where it misses.
        Parallel rays miss.

        The plane distance is computed first; the edge tests run only for rays whose
        plane hit lies in (0, t_best) and within the quad's circumscribed circle.
        """
        if self.compiled is not None:
            return self.compiled(self, k, None, o, d, t_best)
        return _intersect(QuadColumns(self, k), o, d, t_best)

    def intersect_pairs(self, prim: np.ndarray, o: np.ndarray, d: np.ndarray, t_best: np.ndarray) -> np.ndarray:
        """As intersect_one for each ray with its own quad prim[i] (the same arithmetic, so the same t)."""
        if self.compiled is not None:
            return self.compiled(self, -1, prim, o, d, t_best)
        return _intersect(QuadColumns(self, prim), o, d, t_best)

    def boxes(self):
        """(lo, hi) of each quad, (K, 3)."""
        corners = np.stack([self.v00, self.v10, self.v11, self.v01], axis=1)
        return corners.min(axis=1), corners.max(axis=1)

    def surface(self, o, d, t, index):
        """Hit point projected onto the plane, unit normal (rows) and spawn offset."""
        n = self.normal_rows.take(index, axis=1)
        p = o + t * d
        p -= dot(p - self.v00_rows.take(index, axis=1), n) * n
        offset = 64.0 * EPS64 * np.maximum(max_abs3(p), self.scale.take(index))
        return p, n, offset


class QuadColumns:
    """The data of one quad (columns (3, 1), broadcast over the rays) or of one quad per ray
    (rows (3, N), gathered when first asked for), narrowed with the rays as the test discards them."""
    VECTORS = ("v00", "v10", "v11", "v01", "n", "center")

    def __init__(self, quads: QuadSet, k):
        self.quads, self.k, self.single = quads, k, np.ndim(k) == 0

    def take(self, idx) -> "QuadColumns":
        return self if self.single else QuadColumns(self.quads, self.k.take(idx))

    def __getattr__(self, name):
        if name not in self.VECTORS and name != "radius2":
            raise AttributeError(name)
        k = self.k
        if name == "radius2":
            value = self.quads.radius2[k] if self.single else self.quads.radius2.take(k)
        else:
            a = self.quads.vector_rows[self.VECTORS.index(name)]
            value = a[:, k:k + 1] if self.single else a.take(k, axis=1)
        setattr(self, name, value)
        return value


def _intersect(q: QuadColumns, o, d, t_best):
    """The test of QuadSet.intersect_one on quad columns q (one quad, or one per ray)."""
    t_out = np.full(o.shape[1], np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (dot(q.v00, q.n) - dot(q.n, o)) / dot(q.n, d)
    candidate = (t > 0.0) & np.isfinite(t)
    if t_best is not None:
        candidate &= t < t_best
    idx = np.flatnonzero(candidate)
    if len(idx) == 0:
        return t_out
    o, d, t, q = o.take(idx, axis=1), d.take(idx, axis=1), t.take(idx), q.take(idx)
    rel = o + t * d - q.center
    near = np.flatnonzero(dot(rel, rel) <= q.radius2)
    idx, o, d, t, q = idx.take(near), o.take(near, axis=1), d.take(near, axis=1), t.take(near), q.take(near)
    if len(idx) == 0:
        return t_out
    with np.errstate(divide="ignore", invalid="ignore"):
        e01 = q.v10 - q.v00
        e03 = q.v01 - q.v00
        p = cross(d, e03)
        det = dot(p, e01)
        inv = 1.0 / det
        tvec = o - q.v00
        alpha = dot(tvec, p) * inv
        beta = dot(d, cross(tvec, e01)) * inv
        inside = (alpha >= 0.0) & (beta >= 0.0) & (det != 0.0) & np.isfinite(det)
        second = np.flatnonzero(inside & (alpha + beta > 1.0))
        if len(second):
            q2 = q.take(second)
            e23 = q2.v01 - q2.v11
            e21 = q2.v10 - q2.v11
            d2 = d.take(second, axis=1)
            p2 = cross(d2, e21)
            inv2 = 1.0 / dot(p2, e23)
            t2vec = o.take(second, axis=1) - q2.v11
            alpha2 = dot(t2vec, p2) * inv2
            beta2 = dot(d2, cross(t2vec, e23)) * inv2
            inside[second] = (alpha2 >= 0.0) & (beta2 >= 0.0)
    t_out[idx] = np.where(inside, t, np.inf)
    return t_out
