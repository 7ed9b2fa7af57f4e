"""A bounding-volume hierarchy over the boxes of analytic primitives (spheres, quads, the polygons
of Area lights, the bulbs of point lights), traversed for a whole batch of rays at once in NumPy.

Embree (through embreex) takes triangles only, so the exact analytic tests of
engine/geometry/shapes/ keep their own hierarchy: this module only says which (ray, primitive)
pairs can meet; the caller runs its exact test on those pairs, so every hit distance is the one
the test computes for that ray and primitive alone.

The tree is complete and binary over an order of the primitives (as the light tree's, in
engine/lights/selection.py): node j of level L holds the positions K j // 2^L .. K (j + 1) // 2^L - 1,
and each level sorts every node's primitives along the longest axis of their centres, so its two
children are the halves of a median split.  Leaves hold at most LEAF_SIZE primitives.

A query walks the levels breadth-first with (ray, node) pairs, STRIDE levels a step, keeping the
pairs whose box the ray enters before its distance bound; `nearest` then tests each ray's nearest
leaf first and the other leaves only where they begin before the best hit found, so a ray through
a field of primitives tests few of them.  Nothing a ray could hit is ever left out: the boxes are
padded (PAD_RELATIVE of the primitive's size plus PAD_ULPS of its position), and the walk, in
float32 for speed, grows every box by GROW of the largest coordinate in play, which exceeds all of
its rounding; so the hits are the exact tests' own (docs/performance.md, "Many primitives").
"""
from __future__ import annotations

import numpy as np

LEAF_SIZE = 4
PAD_RELATIVE = 1e-6
PAD_ULPS = 16.0 * np.finfo(np.float64).eps
GROW = 2.0 ** -20              # of the largest coordinate: the float32 walk's margin (leaf_pairs)
LIMIT_SLACK = 1.0 + 2.0 ** -20  # the distance bounds, rounded to float32 upward
BOX_SLACK = 1.0 + 1e-9         # a leaf's (float32) entry against a best hit (float64)
STRIDE = 2                     # levels per step of the walk (2: each node's 4 grandchildren at once)


def padded_boxes(lo, hi):
    """(lo, hi) of (K, 3) boxes grown by PAD_RELATIVE of their size and PAD_ULPS of their position."""
    lo, hi = np.asarray(lo, dtype=np.float64).reshape(-1, 3), np.asarray(hi, dtype=np.float64).reshape(-1, 3)
    size = (hi - lo).max(axis=1, initial=0.0)
    scale = np.maximum(np.abs(lo).max(axis=1, initial=0.0), np.abs(hi).max(axis=1, initial=0.0))
    pad = (PAD_RELATIVE * size + PAD_ULPS * scale + 1e-300)[:, None]
    return lo - pad, hi + pad


class BoxTree:
    """The hierarchy over K boxes (lo, hi: (K, 3), already padded: `padded_boxes`)."""

    def __init__(self, lo, hi, leaf_size: int = LEAF_SIZE):
        lo, hi = np.asarray(lo, dtype=np.float64).reshape(-1, 3), np.asarray(hi, dtype=np.float64).reshape(-1, 3)
        self.count = k = len(lo)
        self.depth = int(np.ceil(np.log2(k / leaf_size))) if k > leaf_size else 0
        center = 0.5 * (lo + hi)
        order = np.arange(k)
        for level in range(self.depth):                  # median splits, one level at a time
            start = (k * np.arange(1 << level)) // (1 << level)
            c = center[order]
            extent = np.maximum.reduceat(c, start, axis=0) - np.minimum.reduceat(c, start, axis=0)
            axis = np.argmax(extent, axis=1)
            node = np.searchsorted(start, np.arange(k), side="right") - 1
            order = order[np.lexsort((c[np.arange(k), axis[node]], node))]
        self.order = order
        s_lo, s_hi = lo[order], hi[order]
        tables = []
        for level in range(self.depth + 1):              # node id 2^L - 1 + j, children 2 id + 1, 2 id + 2
            start = (k * np.arange(1 << level)) // (1 << level)
            tables.append(np.concatenate([np.minimum.reduceat(s_lo, start, axis=0),
                                          np.maximum.reduceat(s_hi, start, axis=0)], axis=1))
        box = np.ascontiguousarray(np.concatenate(tables).T) if k else np.zeros((6, 0))        # (6, nodes)
        # float32 (the walk's arithmetic is memory-bound: half the bytes, 2-5x the speed), rounded outward.
        self.box32 = np.concatenate([np.nextafter(box[:3].astype(np.float32), np.float32(-np.inf)),
                                     np.nextafter(box[3:].astype(np.float32), np.float32(np.inf))])
        self.scale = float(np.abs(box).max(initial=0.0))
        leaves = 1 << self.depth
        first = (k * np.arange(leaves + 1)) // leaves
        width = int((first[1:] - first[:-1]).max()) if k else 0
        slot = first[:-1, None] + np.arange(width)[None, :]
        # Primitive of each leaf's slots, -1 past its end; leaf j is node 2^depth - 1 + j.
        self.leaf_prim = np.where(slot < first[1:, None], order[np.minimum(slot, max(k - 1, 0))], -1) if k \
            else np.zeros((1, 0), np.int64)
        self.first_leaf = leaves - 1

    # -- traversal -----------------------------------------------------------------------
    def _enter(self, rays, box, limit, ray, node):
        """(keep, t_near), both shaped as `node` ((P,) or (P, W)): whether ray[p]'s segment
        [0, limit] meets the (grown) box of node[p] (or of each of node[p, :]), and where it enters.
        rays: (6, N) float32 origins and inverse directions; box: the grown float32 boxes."""
        b = box.take(node, axis=1)
        r = rays.take(ray, axis=1)
        lim = limit.take(ray)
        if node.ndim == 2:
            r, lim = r[:, :, None], lim[:, None]
        t_near, t_far = None, None
        for axis in range(3):
            org, iv = r[axis], r[axis + 3]
            t0 = (b[axis] - org) * iv
            t1 = (b[axis + 3] - org) * iv
            # fmin / fmax: a 0 x inf (an origin on a slab of a ray parallel to it) is NaN and ignored.
            near, far = np.fmin(t0, t1), np.fmax(t0, t1)
            t_near = near if t_near is None else np.fmax(t_near, near)
            t_far = far if t_far is None else np.fmin(t_far, far)
        keep = (t_near <= t_far) & (t_far >= 0.0) & (t_near <= lim)
        return keep, t_near

    def leaf_pairs(self, o, d, bound):
        """(ray, leaf, t_near) of every leaf box that ray (rows o, d) enters before bound[ray]
        (+inf: anywhere ahead); rays in order.  The walk goes down STRIDE levels a step, testing
        the 2^STRIDE descendants of each pair's node at once.

        In float32, made conservative: every box grows by GROW x (the largest coordinate of the
        boxes and the ray origins), which exceeds the float32 rounding of origins, inverse
        directions, differences and products (8 ulps and more of those magnitudes), so a ray that
        meets a box in float64 meets the grown box in float32; t_near is then never late."""
        n = o.shape[1]
        if self.count == 0 or n == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            rays = np.empty((6, n), np.float32)
            rays[:3] = o
            np.divide(1.0, d, out=rays[3:], casting="unsafe")
            grow = np.float32(GROW * max(self.scale, float(np.fmax.reduce(np.abs(o), axis=None, initial=0.0))))
            box = np.concatenate([self.box32[:3] - grow, self.box32[3:] + grow])
            limit = (bound * LIMIT_SLACK).astype(np.float32)
            limit = np.where(limit < bound, np.nextafter(limit, np.float32(np.inf)), limit)
            ray = np.arange(n)
            keep, t_near = self._enter(rays, box, limit, ray, np.zeros(n, np.int64))
            ray = np.flatnonzero(keep)
            node, t_near = np.zeros(len(ray), np.int64), t_near.take(ray)
            level = 0
            while level < self.depth:       # (flatnonzero and take: 4x faster than boolean indexing)
                step = min(STRIDE, self.depth - level)
                # The 2^step descendants of a node i, `step` levels down: (i + 1) 2^step - 1 + j.
                below = (node[:, None] + 1) * (1 << step) - 1 + np.arange(1 << step)
                keep, t_near = self._enter(rays, box, limit, ray, below)
                kept = np.flatnonzero(keep)
                ray, node, t_near = ray.take(kept >> step), below.take(kept), t_near.take(kept)
                level += step
        return ray, node - self.first_leaf, t_near

    def prim_pairs(self, ray, leaf):
        """(ray, primitive) pairs of the primitives in each (ray, leaf) pair."""
        prim = self.leaf_prim.take(leaf, axis=0)
        kept = np.flatnonzero(prim >= 0)
        return ray.take(kept // prim.shape[1]), prim.take(kept)

    def all_pairs(self, o, d, bound):
        """(ray, primitive) of every primitive whose box the ray enters before bound[ray]."""
        ray, leaf, _ = self.leaf_pairs(o, d, bound)
        return self.prim_pairs(ray, leaf)

    def nearest(self, o, d, t, test):
        """Nearest hit of each ray among the primitives: (t, prim), where t (N,) holds the bound
        the hits must beat (a hit of another kind or the ray's end; +inf: none) and comes back
        with the hits of this tree that beat it, prim -1 where none did.

        test(ray, prim, bound) -> t of each pair (+inf: a miss) by the exact test, with `bound`
        the ray's current best (the test may skip pairs it knows to be farther).  As the per-
        primitive loop it replaces: a hit replaces the bound only when strictly nearer, and of
        equal distances the lowest primitive number wins."""
        t = np.array(t, dtype=np.float64)
        best = np.full(len(t), -1, dtype=np.int64)
        ray, leaf, t_near = self.leaf_pairs(o, d, t)
        if not len(ray):
            return t, best
        head = _first_minimum(ray, t_near)               # each ray's nearest leaf (rays are in order)
        rest = np.ones(len(ray), bool)
        rest[head] = False
        for sel in (head, np.flatnonzero(rest)):         # the nearest leaf, then what begins before the best
            if sel is not head:
                sel = sel[t_near.take(sel) <= t.take(ray.take(sel)) * BOX_SLACK]
            if len(sel):
                self._merge(t, best, *self.prim_pairs(ray.take(sel), leaf.take(sel)), test)
        return t, best

    @staticmethod
    def _merge(t, best, ray, prim, test):
        """Fold the exact hits of pairs (ray, prim) into (t, best) in place."""
        # The bound one ulp up, so a hit at exactly the current best is reported and the
        # lowest-number rule below decides it (the loop saw the primitives in number order).
        th = test(ray, prim, np.nextafter(t.take(ray), np.inf))
        hit = np.flatnonzero(th < np.inf)
        if not len(hit):
            return
        ray, prim, th = ray.take(hit), prim.take(hit), th.take(hit)
        tied = np.flatnonzero(th == _run_minimum(ray, th))                # per ray: the nearest ...
        lowest = tied[_first_minimum(ray.take(tied), prim.take(tied))]   # ... then the lowest number
        ray, prim, th = ray.take(lowest), prim.take(lowest), th.take(lowest)
        old_t, old = t.take(ray), best.take(ray)
        wins = (th < old_t) | ((th == old_t) & (old >= 0) & (prim < old))
        t[ray[wins]], best[ray[wins]] = th[wins], prim[wins]


def _run_minimum(group, value):
    """For each element, the smallest value of its run of equal `group` numbers (groups in order)."""
    start = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    return np.minimum.reduceat(value, start).repeat(np.diff(np.r_[start, len(group)]))


def _first_minimum(group, value):
    """Index of the first smallest value of each run of equal `group` numbers (groups in order)."""
    at = np.flatnonzero(value == _run_minimum(group, value))
    return at[np.r_[True, group.take(at[1:]) != group.take(at[:-1])]]
