"""The report's octree (2.1.3, 2.2.4) in Python and NumPy, without compiled code of ours.

Build: the scene box is split recursively into eight children; a triangle is stored in
the smallest node that contains it whole (it stays in a node when it straddles that
node's mid-planes), until a node holds few triangles or reaches the depth limit
(coincident triangles cannot recurse forever: docs/hard-cases.md H14).

Traversal: iterative, with an explicit stack, front to back.  Rays are grouped by the
signs of their direction (octant); for a group, visiting children in the order
i XOR octant is front to back for every ray in it, so a hit found in a near child
prunes farther children through `t_entry < t_best`.  The slab test is NaN-tolerant
(np.fmin/np.fmax ignore the NaN of 0 x inf for origins on a slab plane with a zero
direction component: docs/hard-cases.md H13) and pads the exit distance as pbrt does.
"""
from __future__ import annotations

import numpy as np

from .triangles import TriangleArrays, moller_trumbore
from .rows import RowQueries

LEAF_SIZE = 8
MAX_DEPTH = 10
GAMMA3 = 3 * 2.0 ** -53 / (1 - 3 * 2.0 ** -53)


class OctreeAccelerator(RowQueries):
    ray_dtype = np.float64               # what intersect() and occluded() take
    name = "octree"

    def __init__(self, triangles: np.ndarray):
        tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        self.tris = TriangleArrays(tri)
        self.count = len(tri)
        tri_lo, tri_hi = tri.min(axis=1), tri.max(axis=1)
        lo = tri_lo.min(axis=0) if self.count else np.zeros(3)
        hi = tri_hi.max(axis=0) if self.count else np.zeros(3)
        # A cube, slightly enlarged so no triangle lies on the root's faces.
        center = 0.5 * (lo + hi)
        half = 0.5 * (hi - lo).max() * (1 + 1e-6) + 1e-12
        self._lo, self._hi, self._children, self._tri_start, self._tri_end = [], [], [], [], []
        self._order = []
        self._build(np.arange(self.count), tri_lo, tri_hi, center - half, center + half, 0)
        self.node_lo = np.array(self._lo)
        self.node_hi = np.array(self._hi)
        self.children = np.array(self._children, dtype=np.int64)
        self.tri_start = np.array(self._tri_start, dtype=np.int64)
        self.tri_end = np.array(self._tri_end, dtype=np.int64)
        self.tri_order = np.array(self._order, dtype=np.int64)
        self.node_count = len(self.node_lo)
        self.depth = self._depth

    # -- build ---------------------------------------------------------------------
    def _build(self, idx, tri_lo, tri_hi, lo, hi, depth) -> int:
        node = len(self._lo)
        self._lo.append(lo)
        self._hi.append(hi)
        self._children.append([-1] * 8)
        self._tri_start.append(0)
        self._tri_end.append(0)
        self._depth = max(getattr(self, "_depth", 0), depth)
        if len(idx) <= LEAF_SIZE or depth >= MAX_DEPTH:
            stay = idx
            groups = {}
        else:
            mid = 0.5 * (lo + hi)
            low = tri_hi[idx] <= mid           # whole triangle on the low side, per axis
            high = tri_lo[idx] >= mid
            fits = (low | high).all(axis=1)
            octant = (high[:, 0] * 1 + high[:, 1] * 2 + high[:, 2] * 4)
            stay = idx[~fits]
            groups = {c: idx[fits & (octant == c)] for c in range(8)}
        start = len(self._order)
        self._order.extend(stay.tolist())
        self._tri_start[node], self._tri_end[node] = start, len(self._order)
        if groups:
            mid = 0.5 * (lo + hi)
            for c, sub in groups.items():
                if len(sub) == 0:
                    continue
                bits = np.array([c & 1, (c >> 1) & 1, (c >> 2) & 1], dtype=bool)
                clo = np.where(bits, mid, lo)
                chi = np.where(bits, hi, mid)
                self._children[node][c] = self._build(sub, tri_lo, tri_hi, clo, chi, depth + 1)
        return node

    # -- traversal ---------------------------------------------------------------------
    def _slab(self, node, o, inv):
        with np.errstate(invalid="ignore"):
            t0 = (self.node_lo[node] - o) * inv
            t1 = (self.node_hi[node] - o) * inv
        t_near = np.fmax.reduce(np.fmin(t0, t1), axis=1)
        t_far = np.fmin.reduce(np.fmax(t0, t1), axis=1) * (1 + 2 * GAMMA3)
        return t_near, t_far

    def intersect(self, origins, directions, tmax):
        n = len(origins)
        t_best = np.asarray(tmax, dtype=np.float64).copy()
        prim = np.full(n, -1, np.int64)
        u = np.zeros(n)
        v = np.zeros(n)
        if self.count == 0 or n == 0:
            return np.full(n, np.inf), prim, u, v
        with np.errstate(divide="ignore"):
            inv = 1.0 / directions
        neg = np.signbit(directions)
        octant = neg[:, 0] * 1 + neg[:, 1] * 2 + neg[:, 2] * 4
        for oc in range(8):
            rays = np.flatnonzero(octant == oc)
            if len(rays) == 0:
                continue
            visit_order = [i ^ oc for i in range(8)][::-1]   # pushed far first: near pops first
            stack = [(0, rays)]
            while stack:
                node, r = stack.pop()
                t_near, t_far = self._slab(node, origins[r], inv[r])
                keep = (t_near <= t_far) & (t_far >= 0.0) & (t_near < t_best[r])
                r = r[keep]
                if len(r) == 0:
                    continue
                s, e = self.tri_start[node], self.tri_end[node]
                if e > s:
                    tt, which, uu, vv = moller_trumbore(self.tris, self.tri_order[s:e], origins[r], directions[r])
                    closer = tt < t_best[r]
                    if closer.any():
                        rc = r[closer]
                        t_best[rc], prim[rc] = tt[closer], which[closer]
                        u[rc], v[rc] = uu[closer], vv[closer]
                for c in visit_order:
                    child = self.children[node, c]
                    if child >= 0:
                        stack.append((child, r))
        hit = prim >= 0
        return np.where(hit, t_best, np.inf), prim, u, v

    def occluded(self, origins, directions, tmax):
        _, prim, _, _ = self.intersect(origins, directions, tmax)
        return prim >= 0
