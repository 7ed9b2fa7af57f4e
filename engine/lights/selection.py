"""Which light a shading point samples: a pmf P(k | x, n) that can be drawn from and evaluated.

* `PowerSelection`: P(k) proportional to a fixed weight (the report's estimator: area x mean
  radiance), the same for every shading point.
* `LightTree`: the many-lights sampler of Conty Estevez and Kulla, "Importance Sampling of
  Many Lights with Adaptive Tree Splitting" (HPG 2018), without splitting, as Cycles (since
  3.5) and pbrt-v4's BVHLightSampler.  Lights are sorted along a Morton curve and grouped
  into a complete binary tree over that order (node j of level L holds the lights
  floor(K j / 2^L) .. floor(K (j + 1) / 2^L) - 1); each node keeps its power, a bounding
  sphere and a cone bounding its emitters' normals.  A shading point walks down the tree
  choosing each child in proportion to `importance` (power x orientation x receiver cosine /
  distance^2, all bounded so a light that can reach x never gets 0), level by level for
  the whole wavefront at once.  The pmf of a given light (MIS at an emission hit) walks the
  same path, so drawing and evaluating agree exactly.

The tree pmf is mixed with the power pmf (defensive mixing, weight DEFENSIVE), so no light
that carries power is ever given probability 0 by a heuristic.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import dot, rows

DEFENSIVE = 0.05
TINY = np.float32(1e-30)          # floor of the squared distance in the (float32) importance


class PowerSelection:
    def __init__(self, weight):
        weight = np.asarray(weight, dtype=np.float64)
        total = weight.sum()
        self.prob = weight / total if total > 0 else np.full(len(weight), 1.0 / max(len(weight), 1))
        self.cdf = np.cumsum(self.prob)
        self.count = len(weight)

    def sample(self, x, n, u):
        if self.count == 1:
            return np.zeros(len(u), dtype=np.int64), np.ones(len(u))
        light = np.minimum(np.searchsorted(self.cdf, u * self.cdf[-1], side="right"), self.count - 1)
        return light, self.prob.take(light)

    def pmf(self, x, n, light):
        return self.prob.take(light)


def importance(x, n, center, radius, axis, cos_o, power, near2, min2, oriented=True):
    """Importance of light clusters for receivers (x, n) (pbrt-v4 LightBounds::Importance,
    with the distance of Cycles' "max importance").

    center, axis: rows; radius (of the bounding sphere), cos_o (cosine of the normal cone's
    half-angle; -1 = any direction, e.g. two-sided emitters), power: per cluster.  near2: the
    squared distance from x to the cluster's bounding box, clamped below by min2 (the squared
    size of its largest emitter): a receiver inside a cluster of small lamps favours that
    cluster by how close its nearest lamp can be, not by where the cluster's centre is.
    Emission spread theta_e = pi / 2 (Lambertian).  Receivers are opaque: a cluster entirely
    below the tangent plane of x gets 0.  oriented=False skips the emitter-side cone test
    (every cone of the call is the whole sphere, e.g. two-sided lamps).
    """
    w = center - x
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_d = 1.0 / np.sqrt(dot(w, w))
        sin_u = np.minimum(radius * inv_d, 1.0)
        inside = ~(sin_u < 1.0)                          # x in the bounding sphere (or d = 0)
        cos_u = np.where(inside, -1.0, np.sqrt(1.0 - sin_u * sin_u))
        sin_u = np.where(inside, 0.0, sin_u)
        # Receiver side: theta_i = angle(n, w), reduced by theta_u.
        cos_i = dot(n, w) * inv_d
        sin_i = np.sqrt(np.maximum(1.0 - cos_i * cos_i, 0.0))
        cos_r = np.where(inside | (cos_i > cos_u), 1.0, cos_i * cos_u + sin_i * sin_u)
        result = power * np.maximum(cos_r, 0.0) / np.maximum(np.maximum(near2, min2), TINY)
        if oriented:
            # Emitter side: theta = angle(axis, -w), reduced by the cone's half-angle and theta_u.
            cos_t = -dot(axis, w) * inv_d
            sin_t = np.sqrt(np.maximum(1.0 - cos_t * cos_t, 0.0))
            sin_o = np.sqrt(np.maximum(1.0 - cos_o * cos_o, 0.0))
            beyond = cos_t <= cos_o
            cos_a = np.where(beyond, cos_t * cos_o + sin_t * sin_o, 1.0)
            sin_a = np.where(beyond, sin_t * cos_o - cos_t * sin_o, 0.0)
            cos_e = np.where(inside | (cos_a > cos_u), 1.0, cos_a * cos_u + sin_a * sin_u)
            result = result * np.maximum(cos_e, 0.0)
    return result


def box_distance2(x, lo, hi):
    """Squared distance from points x to boxes [lo, hi] (rows); 0 inside."""
    d2 = 0.0
    for axis in range(3):
        gap = np.maximum(np.maximum(lo[axis] - x[axis], x[axis] - hi[axis]), 0.0)
        d2 = d2 + gap * gap
    return d2


def morton_order(points: np.ndarray) -> np.ndarray:
    """Order of (K, 3) points along a 30-bit Morton (Z-order) curve."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    q = ((points - lo) / np.maximum(hi - lo, 1e-300) * 1023.0).astype(np.int64)
    code = np.zeros(len(points), dtype=np.int64)
    for bit in range(10):
        for axis in range(3):
            code |= ((q[:, axis] >> bit) & 1) << (3 * bit + axis)
    return np.argsort(code, kind="stable")


class LightTree:
    def __init__(self, center, radius, axis, cos_o, power, fallback_weight, backend="numpy"):
        """center, axis: (K, 3); radius, cos_o, power: (K,).  fallback_weight: the defensive pmf.
        backend: "numba" walks the tree with the compiled twin (engine/lights/selection_jit.py,
        the same numbers), "numpy" here (engine/core/backend.py chooses)."""
        center, axis = np.asarray(center, float).reshape(-1, 3), np.asarray(axis, float).reshape(-1, 3)
        radius, cos_o, power = (np.asarray(a, float).reshape(-1) for a in (radius, cos_o, power))
        self.count = k = len(power)
        self.fallback = PowerSelection(fallback_weight)
        self.depth = int(np.ceil(np.log2(k))) if k > 1 else 0
        order = morton_order(center) if k > 1 else np.zeros(1, np.int64)
        self.light_at = order                                    # sorted position -> light
        self.position_of = np.empty(k, dtype=np.int64)
        self.position_of[order] = np.arange(k)
        c, r, a, co, p = center[order], radius[order], axis[order], cos_o[order], power[order]
        lo, hi = c - r[:, None], c + r[:, None]
        theta_o = np.arccos(np.clip(co, -1.0, 1.0))
        self.levels = [None]                                     # level 0 (the root) is never tested
        for level in range(1, self.depth + 1):
            nodes = 1 << level
            start = (k * np.arange(nodes)) // nodes
            end = (k * np.arange(1, nodes + 1)) // nodes
            empty = end == start
            node_power = np.where(empty, 0.0, np.add.reduceat(p, start))
            box_lo = np.minimum.reduceat(lo, start, axis=0)
            box_hi = np.maximum.reduceat(hi, start, axis=0)
            mean_axis = np.add.reduceat(a * np.maximum(p, 1e-300)[:, None], start, axis=0)
            length = np.linalg.norm(mean_axis, axis=1)[:, None]
            # Any unit axis bounds the members with the widest member angle about it.
            node_axis = np.where(length > 0.0, mean_axis / np.maximum(length, 1e-300), [0.0, 0.0, 1.0])
            owner = np.searchsorted(start, np.arange(k), side="right") - 1
            spread = np.arccos(np.clip(np.einsum("ij,ij->i", node_axis[owner], a), -1.0, 1.0)) + theta_o
            node_theta = np.minimum(np.maximum.reduceat(spread, start), np.pi)
            # One float32 table per level (importance is a heuristic: float32 halves its cost), so
            # a child's bounds are gathered with a single take: rows as NODE_ROWS says.
            table = np.vstack([rows(0.5 * (box_lo + box_hi)), rows(box_lo), rows(box_hi), rows(node_axis),
                               0.5 * np.linalg.norm(box_hi - box_lo, axis=1), np.cos(node_theta),
                               node_power / max(p.sum(), 1e-300), np.maximum.reduceat(r, start) ** 2])
            self.levels.append(dict(table=table.astype(np.float32), power=table[14].copy(), empty=empty,
                                    oriented=bool((node_theta < np.pi).any())))
        self.backend = backend
        self._compiled = None
        if backend == "numba" and self.depth:
            from .selection_jit import TreeTables
            self._compiled = TreeTables(self)

    def _left_probability(self, x, n, level, left):
        nodes = self.levels[level]

        def imp(node):
            b = nodes["table"].take(node, axis=1)          # centre, lo, hi, axis, radius, cos_o, power, min2
            return importance(x, n, b[0:3], b[12], b[9:12], b[13], b[14], box_distance2(x, b[3:6], b[6:9]),
                              b[15], nodes["oriented"])
        i_left, i_right = imp(left), imp(left + 1)
        total = i_left + i_right
        p_left, p_right = nodes["power"].take(left), nodes["power"].take(left + 1)   # float64
        by_power = np.where(p_left + p_right > 0.0, p_left / np.maximum(p_left + p_right, 1e-300), 0.5)
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.where(total > 0.0, i_left / total, by_power).astype(np.float64)
        # Never walk into an empty child (the tree is complete over a Morton order of K lights).
        return np.where(nodes["empty"].take(left + 1), 1.0, np.where(nodes["empty"].take(left), 0.0, p))

    def _tree_sample(self, x, n, u):
        if self._compiled is not None:
            return self._compiled.sample(x, n, u)
        node = np.zeros(len(u), dtype=np.int64)
        pmf = np.ones(len(u))
        for level in range(1, self.depth + 1):
            left = 2 * node
            p = self._left_probability(x, n, level, left)
            go_left = u < p
            with np.errstate(divide="ignore", invalid="ignore"):
                u = np.where(go_left, u / p, (u - p) / (1.0 - p))
            u = np.clip(np.nan_to_num(u), 0.0, np.nextafter(1.0, 0.0))
            pmf *= np.where(go_left, p, 1.0 - p)
            node = np.where(go_left, left, left + 1)
        position = (self.count * node) >> self.depth
        return self.light_at.take(position), pmf

    def _tree_pmf(self, x, n, light):
        if self._compiled is not None:
            return self._compiled.pmf(x, n, light)
        position = self.position_of.take(light)
        node = np.zeros(len(light), dtype=np.int64)
        pmf = np.ones(len(light))
        for level in range(1, self.depth + 1):
            left = 2 * node
            split = (self.count * (left + 1)) >> level           # first position of the right child
            go_left = position < split
            p = self._left_probability(x, n, level, left)
            pmf *= np.where(go_left, p, 1.0 - p)
            node = np.where(go_left, left, left + 1)
        return pmf

    def sample(self, x, n, u):
        if self.count == 1:
            return np.zeros(len(u), dtype=np.int64), np.ones(len(u))
        if self._compiled is not None:                   # all of the below in one loop
            return self._compiled.select(x, n, u, DEFENSIVE)
        x, n = x.astype(np.float32), n.astype(np.float32)
        defensive = u < DEFENSIVE
        light, tree_pmf = self._tree_sample(x, n, np.where(defensive, 0.0, (u - DEFENSIVE) / (1.0 - DEFENSIVE)))
        sel = np.flatnonzero(defensive)
        if len(sel):
            light[sel], _ = self.fallback.sample(None, None, u.take(sel) / DEFENSIVE)
            tree_pmf[sel] = self._tree_pmf(x.take(sel, axis=1), n.take(sel, axis=1), light.take(sel))
        return light, DEFENSIVE * self.fallback.pmf(x, n, light) + (1.0 - DEFENSIVE) * tree_pmf

    def pmf(self, x, n, light):
        if self.count == 1:
            return np.ones(len(light))
        if self._compiled is not None:
            return self._compiled.mixed_pmf(x, n, light, DEFENSIVE)
        x, n = x.astype(np.float32), n.astype(np.float32)
        return DEFENSIVE * self.fallback.pmf(x, n, light) + (1.0 - DEFENSIVE) * self._tree_pmf(x, n, light)
