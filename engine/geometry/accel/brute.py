"""No acceleration: every ray against every triangle (the report's "no octree" row)."""
from __future__ import annotations

import numpy as np

from .triangles import TriangleArrays, moller_trumbore
from .rows import RowQueries

# Pairs (rays x triangles) per chunk, to bound memory.
PAIRS_PER_CHUNK = 1 << 20


class BruteForceAccelerator(RowQueries):
    ray_dtype = np.float64               # what intersect() and occluded() take
    name = "brute"

    def __init__(self, triangles: np.ndarray):
        self.tris = TriangleArrays(triangles)
        self.count = self.tris.count

    def intersect(self, origins, directions, tmax):
        n = len(origins)
        t = np.asarray(tmax, dtype=np.float64).copy()
        prim = np.full(n, -1, np.int64)
        u = np.zeros(n)
        v = np.zeros(n)
        rays_per_chunk = max(1, PAIRS_PER_CHUNK // max(1, self.count))
        tri_chunk = max(1, PAIRS_PER_CHUNK // max(1, min(n, rays_per_chunk)))
        for r0 in range(0, n, rays_per_chunk):
            rs = slice(r0, r0 + rays_per_chunk)
            for k0 in range(0, self.count, tri_chunk):
                idx = np.arange(k0, min(k0 + tri_chunk, self.count))
                tt, which, uu, vv = moller_trumbore(self.tris, idx, origins[rs], directions[rs])
                closer = tt < t[rs]
                t[rs] = np.where(closer, tt, t[rs])
                prim[rs] = np.where(closer, which, prim[rs])
                u[rs] = np.where(closer, uu, u[rs])
                v[rs] = np.where(closer, vv, v[rs])
        hit = prim >= 0
        return np.where(hit, t, np.inf), prim, u, v

    def occluded(self, origins, directions, tmax):
        t, prim, _, _ = self.intersect(origins, directions, tmax)
        return prim >= 0
