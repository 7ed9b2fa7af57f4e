"""All primitives of a scene behind one nearest-hit and one shadow-ray query.

Triangles go to the accelerator (Embree); spheres and quads are analytic.  A kernel
runs only if the scene has that kind of primitive (the effect plan).  The nearest hit
is merged with `<` on arrays whose misses are +inf, so a NaN distance can never win
(np.argmin would pick it: hard case H7).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .accel import build_accelerator
from .shapes.quads import QuadSet
from .shapes.spheres import intersect_sphere, surface_point

NONE, TRIANGLE, SPHERE, QUAD = 0, 1, 2, 3

# Spawn offset for Embree triangles, relative to the largest coordinate of the hit
# point or its triangle: about 16 float32 ulps, which covers rounding the origin to
# float32 for Embree plus Embree's own float32 plane test (hard cases H1-H3).
TRIANGLE_OFFSET = 2.0 ** -20


@dataclass
class SurfaceHits:
    """Shading data for the rays that hit something."""
    point: np.ndarray      # (M, 3) float64, on the surface
    normal: np.ndarray     # (M, 3) unit geometric normal (winding / outward)
    material: np.ndarray   # (M,) material index
    offset: np.ndarray     # (M,) distance along the normal that clears the surface


class Counters:
    """Per-worker ray counts and time spent inside intersection kernels."""

    def __init__(self):
        self.rays = {"camera": 0, "extension": 0, "shadow": 0}
        self.seconds_in_intersection = 0.0
        self.seconds_in_embree = 0.0
        self.nonfinite_samples = 0

    def merge(self, other: "Counters") -> None:
        for key, value in other.rays.items():
            self.rays[key] += value
        self.seconds_in_intersection += other.seconds_in_intersection
        self.seconds_in_embree += other.seconds_in_embree
        self.nonfinite_samples += other.nonfinite_samples


class SceneGeometry:
    def __init__(self, scene, accelerator: str = "embree"):
        tris, tri_mats = [], []
        for mesh in scene.meshes:
            if len(mesh.triangles):
                tris.append(mesh.vertices[mesh.triangles])
                tri_mats.append(mesh.material_ids)
        self.triangles = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
        self.triangle_material = np.concatenate(tri_mats) if tri_mats else np.zeros(0, np.int64)
        v0, v1, v2 = self.triangles[:, 0], self.triangles[:, 1], self.triangles[:, 2]
        self.tri_v0, self.tri_e1, self.tri_e2 = v0, v1 - v0, v2 - v0
        normal = np.cross(self.tri_e1, self.tri_e2)
        self.tri_normal = normal / np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
        self.tri_scale = np.abs(self.triangles).max(axis=(1, 2)) if len(self.triangles) else np.zeros(0)

        self.sphere_center = np.array([s.center for s in scene.spheres], dtype=np.float64).reshape(-1, 3)
        self.sphere_radius = np.array([s.radius for s in scene.spheres], dtype=np.float64)
        self.sphere_material = np.array([s.material_id for s in scene.spheres], dtype=np.int64)

        self.quads = QuadSet(np.array([q.corners for q in scene.quads]).reshape(-1, 4, 3))
        self.quad_material = np.array([q.material_id for q in scene.quads], dtype=np.int64)

        self.has_triangles = len(self.triangles) > 0
        self.has_spheres = len(self.sphere_radius) > 0
        self.has_quads = self.quads.count > 0
        start = time.perf_counter()
        self.accelerator = build_accelerator(accelerator, self.triangles) if self.has_triangles else None
        self.build_seconds = time.perf_counter() - start

    # -- queries -----------------------------------------------------------------
    def intersect(self, origins, directions, counters: Counters, tmax=None):
        """Nearest hit of each ray: (t, kind, prim, u, v); t = +inf and kind = NONE on a miss."""
        n = len(origins)
        start = time.perf_counter()
        t = np.full(n, np.inf) if tmax is None else np.asarray(tmax, dtype=np.float64).copy()
        kind = np.zeros(n, dtype=np.int8)
        prim = np.full(n, -1, dtype=np.int64)
        u = v = np.zeros(n)
        if self.has_triangles:
            t0 = time.perf_counter()
            tt, tp, u, v = self.accelerator.intersect(origins, directions, t)
            counters.seconds_in_embree += time.perf_counter() - t0
            closer = tt < t
            t = np.where(closer, tt, t)
            kind[closer] = TRIANGLE
            prim[closer] = tp[closer]
        for k in range(len(self.sphere_radius)) if self.has_spheres else ():
            ts = intersect_sphere(origins, directions, self.sphere_center[k], self.sphere_radius[k], t)
            closer = ts < t
            t = np.where(closer, ts, t)
            kind[closer] = SPHERE
            prim[closer] = k
        for k in range(self.quads.count) if self.has_quads else ():
            tq = self.quads.intersect_one(k, origins, directions, t)
            closer = tq < t
            t = np.where(closer, tq, t)
            kind[closer] = QUAD
            prim[closer] = k
        kind[~np.isfinite(t)] = NONE
        if tmax is not None:
            t[kind == NONE] = np.inf
        counters.seconds_in_intersection += time.perf_counter() - start
        return t, kind, prim, u, v

    def occluded(self, origins, directions, tmax, counters: Counters):
        """True where something lies on the segment (0, tmax) of the ray."""
        start = time.perf_counter()
        blocked = np.zeros(len(origins), dtype=bool)
        if self.has_triangles:
            t0 = time.perf_counter()
            blocked |= self.accelerator.occluded(origins, directions, tmax)
            counters.seconds_in_embree += time.perf_counter() - t0
        rest = ~blocked
        if (self.has_spheres or self.has_quads) and rest.any():
            o, d, tm = origins[rest], directions[rest], tmax[rest]
            hit = np.zeros(len(o), dtype=bool)
            for k in range(len(self.sphere_radius)):
                hit |= intersect_sphere(o, d, self.sphere_center[k], self.sphere_radius[k], tm) < tm
            for k in range(self.quads.count):
                hit |= self.quads.intersect_one(k, o, d, tm) < tm
            blocked[rest] = hit
        counters.seconds_in_intersection += time.perf_counter() - start
        return blocked

    def surface(self, origins, directions, t, kind, prim, u, v) -> SurfaceHits:
        """Shading data for rays that hit (all arrays already restricted to hits)."""
        m = len(t)
        if self.has_triangles and (kind == TRIANGLE).all():   # fast path: triangles only
            return self._triangle_surface(prim, u, v)
        point = np.empty((m, 3))
        normal = np.empty((m, 3))
        material = np.empty(m, dtype=np.int64)
        offset = np.empty(m)
        sel = kind == TRIANGLE
        if sel.any():
            tri = self._triangle_surface(prim[sel], u[sel], v[sel])
            point[sel], normal[sel], material[sel], offset[sel] = tri.point, tri.normal, tri.material, tri.offset
        sel = kind == SPHERE
        if sel.any():
            p = prim[sel]
            pt, nrm, off = surface_point(origins[sel], directions[sel], t[sel],
                                         self.sphere_center[p], self.sphere_radius[p])
            point[sel], normal[sel], offset[sel] = pt, nrm, off
            material[sel] = self.sphere_material[p]
        sel = kind == QUAD
        if sel.any():
            p = prim[sel]
            pt, nrm, off = self.quads.surface(origins[sel], directions[sel], t[sel], p)
            point[sel], normal[sel], offset[sel] = pt, nrm, off
            material[sel] = self.quad_material[p]
        return SurfaceHits(point, normal, material, offset)

    def _triangle_surface(self, prim, u, v) -> SurfaceHits:
        # Barycentric interpolation in float64 puts the point on the triangle's plane
        # (pbrt): the float32 error of o + t d would be along the ray instead.
        point = self.tri_v0[prim] + u[:, None] * self.tri_e1[prim] + v[:, None] * self.tri_e2[prim]
        offset = TRIANGLE_OFFSET * np.maximum(np.abs(point).max(axis=1), self.tri_scale[prim])
        return SurfaceHits(point, self.tri_normal[prim], self.triangle_material[prim], offset)
