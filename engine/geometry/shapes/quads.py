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

    def __init__(self, corners: np.ndarray):
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

    def intersect_one(self, k: int, o: np.ndarray, d: np.ndarray,
                      t_best: np.ndarray | None = None) -> np.ndarray:
        """t > 0 of each ray (rows, see engine/core/vec.py) with quad k, +inf where it misses.
        Parallel rays miss.

        The plane distance is computed first; the edge tests run only for rays whose
        plane hit lies in (0, t_best) and within the quad's circumscribed circle.
        """
        v00, v10, v11, v01, n = self.v00[k], self.v10[k], self.v11[k], self.v01[k], self.normal[k]
        t_out = np.full(o.shape[1], np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (dot(v00, n) - dot(n, o)) / dot(n, d)
        candidate = (t > 0.0) & np.isfinite(t)
        if t_best is not None:
            candidate &= t < t_best
        idx = np.flatnonzero(candidate)
        if len(idx) == 0:
            return t_out
        o, d, t = o.take(idx, axis=1), d.take(idx, axis=1), t.take(idx)
        rel = o + t * d - self.center[k][:, None]
        near = np.flatnonzero(dot(rel, rel) <= self.radius2[k])
        idx, o, d, t = idx.take(near), o.take(near, axis=1), d.take(near, axis=1), t.take(near)
        if len(idx) == 0:
            return t_out
        with np.errstate(divide="ignore", invalid="ignore"):
            e01 = v10 - v00
            e03 = v01 - v00
            p = cross(d, e03)
            det = dot(p, e01)
            inv = 1.0 / det
            tvec = o - v00[:, None]
            alpha = dot(tvec, p) * inv
            beta = dot(d, cross(tvec, e01)) * inv
            inside = (alpha >= 0.0) & (beta >= 0.0) & (det != 0.0) & np.isfinite(det)
            second = np.flatnonzero(inside & (alpha + beta > 1.0))
            if len(second):
                e23 = v01 - v11
                e21 = v10 - v11
                d2 = d.take(second, axis=1)
                p2 = cross(d2, e21)
                inv2 = 1.0 / dot(p2, e23)
                t2vec = o.take(second, axis=1) - v11[:, None]
                alpha2 = dot(t2vec, p2) * inv2
                beta2 = dot(d2, cross(t2vec, e23)) * inv2
                inside[second] = (alpha2 >= 0.0) & (beta2 >= 0.0)
        t_out[idx] = np.where(inside, t, np.inf)
        return t_out

    def surface(self, o, d, t, index):
        """Hit point projected onto the plane, unit normal (rows) and spawn offset."""
        n = self.normal_rows.take(index, axis=1)
        p = o + t * d
        p -= dot(p - self.v00_rows.take(index, axis=1), n) * n
        offset = 64.0 * EPS64 * np.maximum(max_abs3(p), self.scale.take(index))
        return p, n, offset
