"""Blender Area lights as ray targets: planar convex polygons that rays can reach but that
cast no shadow (as Cycles' lamps with Multiple Importance on).

Only nearest-hit queries test them, and each light only for the ray kinds it is visible to
(Cycles' ray visibility: 0 camera, 1 diffuse, 2 glossy, 3 transmission).  A ray that
reaches a light adds its emission and goes on through it (the integrator's pass-through
stage).  Rows as everywhere (engine/core/vec.py).
"""
from __future__ import annotations

import numpy as np

from ...core.vec import cross, dot, max_abs3

EPS64 = np.finfo(np.float64).eps
RAY_KINDS = ("camera", "diffuse", "glossy", "transmission")


class LightPolygons:
    def __init__(self, lights, backend: str = "numpy"):
        """backend (engine/core/backend.py): "numba" tests with the compiled twin
        (engine/geometry/shapes/light_polygons_jit.py, the same t), "numpy" with `_intersect` below."""
        self.count = len(lights)
        self.corners = [np.asarray(light.vertices, dtype=np.float64).reshape(-1, 3) for light in lights]
        # Corner i of every light as rows (corners, 3, K), each polygon padded with its last corner.
        self.size = np.array([len(c) for c in self.corners], dtype=np.int64)
        self.sizes_present = sorted(set(self.size.tolist()))
        width = int(self.size.max()) if self.count else 0
        self.corner_rows = np.zeros((width, 3, self.count))
        for size in self.sizes_present:
            sel = np.flatnonzero(self.size == size)
            c = np.array([self.corners[k] for k in sel])                   # (G, size, 3)
            self.corner_rows[:, :, sel] = c[:, np.minimum(np.arange(width), size - 1)].transpose(1, 2, 0)
        # The fan's cross products summed in corner order, each as np.cross gives it.
        c0 = self.corner_rows[0] if self.count else np.zeros((3, 0))
        n = np.zeros((3, self.count))
        for i in range(1, width - 1):
            sel = np.flatnonzero(self.size > i + 1)
            n[:, sel] += cross(self.corner_rows[i] - c0, self.corner_rows[i + 1] - c0)[:, sel]
        length = np.sqrt(np.array([row.dot(row) for row in n.T]))         # np.linalg.norm of each
        self.normal = (n / np.maximum(length, 1e-300)).T.reshape(-1, 3).copy()
        self.normal_rows = np.ascontiguousarray(self.normal.T)
        self.origin = np.ascontiguousarray(c0.T)
        self.scale = np.abs(self.corner_rows).max(axis=(0, 1)) if self.count else np.zeros(0)
        self.radiance = np.array([light.radiance for light in lights], dtype=np.float64).reshape(-1, 3).T.copy()
        self.two_sided = np.array([light.two_sided for light in lights], dtype=bool)
        self.visible = np.array([[getattr(light, f"visible_{kind}") for kind in RAY_KINDS] for light in lights],
                                dtype=bool).reshape(-1, len(RAY_KINDS))
        self.compiled = None
        if backend == "numba" and self.count:
            from . import light_polygons_jit
            self.compiled = light_polygons_jit.intersect

    def rays_that_see(self, k: int, ray_kind: np.ndarray | None) -> np.ndarray | None:
        """Indices of the rays light k is visible to (None: all of them)."""
        vis = self.visible[k]
        if ray_kind is None or vis.all():
            return None
        return np.flatnonzero(vis.take(ray_kind))

    def rays_that_see_any(self, ray_kind: np.ndarray | None) -> np.ndarray | None:
        """Indices of the rays at least one light is visible to (None: all of them)."""
        seen = self.visible.any(axis=0)
        if ray_kind is None or seen.all():
            return None
        return np.flatnonzero(seen.take(ray_kind))

    def intersect_one(self, k: int, o, d, t_best):
        """t > 0 of each ray with light k's polygon, +inf where it misses (either face)."""
        if self.compiled is not None:
            return self.compiled(self, k, None, None, o, d, t_best)
        c = self.corner_rows[:len(self.corners[k]), :, k:k + 1]
        return _intersect(list(c), self.normal_rows[:, k:k + 1], o, d, t_best, single=True)

    def intersect_pairs(self, prim, o, d, t_best, ray_kind=None):
        """As intersect_one for each ray with its own light prim[i] (the same arithmetic, so the same
        t), +inf where that light is not visible to the ray's kind (ray_kind: each ray's, or None)."""
        if self.compiled is not None:
            return self.compiled(self, -1, prim, None if ray_kind is None else self.visible[prim, ray_kind],
                                 o, d, t_best)
        t_out = np.full(len(prim), np.inf)
        if ray_kind is not None:
            sees = self.visible[prim, ray_kind]
        for size in self.sizes_present:                  # polygons of one corner count at a time
            sel = np.flatnonzero((self.size.take(prim) == size) & (True if ray_kind is None else sees))
            if len(sel):
                k = prim.take(sel)
                corners = [self.corner_rows[i].take(k, axis=1) for i in range(size)]
                t_out[sel] = _intersect(corners, self.normal_rows.take(k, axis=1), o.take(sel, axis=1),
                                        d.take(sel, axis=1), t_best.take(sel), single=False)
        return t_out

    def boxes(self):
        """(lo, hi) of each polygon, (K, 3)."""
        return self.corner_rows.min(axis=0).T, self.corner_rows.max(axis=0).T

    def surface(self, o, d, t, index):
        n = self.normal[index].T.copy()
        p = o + t * d
        p -= dot(p - self.origin[index].T, n) * n
        offset = 64.0 * EPS64 * np.maximum(max_abs3(p), self.scale.take(index))
        return p, n, offset


def _intersect(corners, n, o, d, t_best, single: bool):
    """The polygon test on corner columns (3, 1) of one light (single) or rows (3, N), one light per ray."""
    t_out = np.full(o.shape[1], np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (dot(corners[0], n) - dot(n, o)) / dot(n, d)
    candidate = np.flatnonzero((t > 0.0) & np.isfinite(t) & (t < t_best))
    if len(candidate) == 0:
        return t_out
    if not single:
        corners, n = [c.take(candidate, axis=1) for c in corners], n.take(candidate, axis=1)
    t = t.take(candidate)
    p = o.take(candidate, axis=1) + t * d.take(candidate, axis=1)
    inside = np.ones(len(candidate), dtype=bool)
    for i in range(len(corners)):                    # convex, counter-clockwise about n
        edge = corners[(i + 1) % len(corners)] - corners[i]
        inside &= dot(cross(edge, p - corners[i]), n) >= 0.0
    t_out[candidate] = np.where(inside, t, np.inf)
    return t_out
