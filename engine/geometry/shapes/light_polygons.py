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
    def __init__(self, lights):
        self.count = len(lights)
        self.corners = [np.asarray(light.vertices, dtype=np.float64).reshape(-1, 3) for light in lights]
        normals = []
        for c in self.corners:
            n = np.zeros(3)
            for i in range(1, len(c) - 1):
                n += np.cross(c[i] - c[0], c[i + 1] - c[0])
            normals.append(n / max(np.linalg.norm(n), 1e-300))
        self.normal = np.array(normals).reshape(-1, 3)
        self.origin = np.array([c[0] for c in self.corners]).reshape(-1, 3)
        self.scale = np.array([np.abs(c).max() for c in self.corners])
        self.radiance = np.array([light.radiance for light in lights], dtype=np.float64).reshape(-1, 3).T.copy()
        self.two_sided = np.array([light.two_sided for light in lights], dtype=bool)
        self.visible = np.array([[getattr(light, f"visible_{kind}") for kind in RAY_KINDS] for light in lights],
                                dtype=bool).reshape(-1, len(RAY_KINDS))

    def rays_that_see(self, k: int, ray_kind: np.ndarray | None) -> np.ndarray | None:
        """Indices of the rays light k is visible to (None: all of them)."""
        vis = self.visible[k]
        if ray_kind is None or vis.all():
            return None
        return np.flatnonzero(vis.take(ray_kind))

    def intersect_one(self, k: int, o, d, t_best):
        """t > 0 of each ray with light k's polygon, +inf where it misses (either face)."""
        c, n = self.corners[k], self.normal[k]
        t_out = np.full(o.shape[1], np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (dot(c[0], n) - dot(n, o)) / dot(n, d)
        candidate = np.flatnonzero((t > 0.0) & np.isfinite(t) & (t < t_best))
        if len(candidate) == 0:
            return t_out
        t = t.take(candidate)
        p = o.take(candidate, axis=1) + t * d.take(candidate, axis=1)
        inside = np.ones(len(candidate), dtype=bool)
        for i in range(len(c)):                      # convex, counter-clockwise about n
            edge = c[(i + 1) % len(c)] - c[i]
            inside &= dot(cross(edge, p - c[i][:, None]), n) >= 0.0
        t_out[candidate] = np.where(inside, t, np.inf)
        return t_out

    def surface(self, o, d, t, index):
        n = self.normal[index].T.copy()
        p = o + t * d
        p -= dot(p - self.origin[index].T, n) * n
        offset = 64.0 * EPS64 * np.maximum(max_abs3(p), self.scale.take(index))
        return p, n, offset
