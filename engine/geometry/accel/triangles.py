"""Möller-Trumbore ray-triangle test, vectorised over rays x triangles, in float64.

Used by the brute-force and octree accelerators (report 2.2.3).  Degenerate
triangles (det = 0) and rays parallel to the plane never hit; no NaN escapes.
"""
from __future__ import annotations

import numpy as np


class TriangleArrays:
    """Triangles as v0, e1 = v1 - v0, e2 = v2 - v0 arrays."""

    def __init__(self, triangles: np.ndarray):
        tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        self.v0 = np.ascontiguousarray(tri[:, 0])
        self.e1 = np.ascontiguousarray(tri[:, 1] - tri[:, 0])
        self.e2 = np.ascontiguousarray(tri[:, 2] - tri[:, 0])
        self.count = len(tri)


def moller_trumbore(tris: TriangleArrays, tri_idx: np.ndarray, origins: np.ndarray,
                    directions: np.ndarray):
    """Test every ray against every triangle in tri_idx.

    Returns (t, which, u, v) per ray: nearest t > 0 (+inf if none), the triangle index
    (from tri_idx; -1 if none) and its barycentrics.
    """
    m = len(origins)
    if len(tri_idx) == 0 or m == 0:
        return np.full(m, np.inf), np.full(m, -1, np.int64), np.zeros(m), np.zeros(m)
    v0 = tris.v0[tri_idx][None]          # (1, k, 3)
    e1 = tris.e1[tri_idx][None]
    e2 = tris.e2[tri_idx][None]
    d = directions[:, None, :]           # (m, 1, 3)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        p = np.cross(d, e2)
        det = (e1 * p).sum(axis=2)
        inv = 1.0 / det
        tvec = origins[:, None, :] - v0
        u = (tvec * p).sum(axis=2) * inv
        q = np.cross(tvec, e1)
        v = (d * q).sum(axis=2) * inv
        t = (e2 * q).sum(axis=2) * inv
        ok = (det != 0.0) & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t > 0.0) & np.isfinite(t)
    t = np.where(ok, t, np.inf)
    best = np.argmin(t, axis=1)          # safe: no NaN left, misses are +inf
    rows = np.arange(m)
    t_best = t[rows, best]
    hit = np.isfinite(t_best)
    which = np.where(hit, tri_idx[best], -1)
    return t_best, which, np.where(hit, u[rows, best], 0.0), np.where(hit, v[rows, best], 0.0)
