"""All primitives of a scene behind one nearest-hit and one shadow-ray query.

Triangles go to the accelerator (Embree, or the octree / brute force); spheres, quads and
the polygons of Blender Area lights are analytic: up to LOOP_MAX of a kind are tested one after
the other over all rays, more through a BoxTree (engine/geometry/shapes/box_tree.py) that gives
the same hits.  Rays and surface vectors are rows, (3, N)
arrays (engine/core/vec.py).  A kernel runs only if the effect plan switches it on (the plan is
the one place that decides; it says why).  Area lights are tested by nearest-hit queries
only (they cast no shadow) and only for the ray kinds they are visible to.  The nearest hit
is merged with `<` on arrays whose misses are +inf, so a NaN distance can never win
(np.argmin would pick it: docs/hard-cases.md H7).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .accel import build_accelerator
from .shapes.box_tree import BoxTree, padded_boxes
from .shapes.light_polygons import LightPolygons
from .shapes.quads import QuadSet
from .shading_normals import SmoothNormals, has_smooth
from .shapes.spheres import EPS64, sphere_kernel, sphere_loop_kernels, surface_point
from ..core.vec import cross_rows, max_abs3, norm, rows, triangle_rows

NONE, TRIANGLE, SPHERE, QUAD, LIGHT = 0, 1, 2, 3, 4
KINDS = (TRIANGLE, SPHERE, QUAD, LIGHT)

# Spawn offset for Embree triangles, relative to the largest coordinate of the hit
# point or its triangle: about 16 float32 ulps, which covers rounding the origin to
# float32 for Embree plus Embree's own float32 plane test (docs/hard-cases.md H1-H3).
TRIANGLE_OFFSET = 2.0 ** -20

# Up to this many spheres (quads, Area lights) are tested one after the other over all rays, more
# through a BoxTree: about where the two cost the same (docs/performance.md "Many primitives").
LOOP_MAX = {"spheres": 48, "quads": 16, "lights": 16}


@dataclass
class SurfaceHits:
    """Shading data for the rays that hit something."""
    point: np.ndarray      # (3, M) float64, on the surface
    normal: np.ndarray     # (3, M) unit geometric normal (winding / outward)
    material: np.ndarray   # (M,) material index
    offset: np.ndarray     # (M,) distance along the normal that clears the surface
    shading: np.ndarray | None = None   # (3, M) unit shading normal (smooth triangles); else `normal`
    facing: np.ndarray | None = None    # (3, M) `normal` turned towards the ray, when computed with it

    def __post_init__(self):
        if self.shading is None:
            self.shading = self.normal


@dataclass
class HitSet:
    """Nearest hits of a batch, compacted and sorted by (group, primitive kind).

    ``index`` lists the rays that hit, ordered so that every (group, kind) pair forms
    one contiguous run (``runs[(group, kind)] = (start, stop)``) and every group one
    contiguous range (``groups[g] = (start, stop)``); ``miss`` lists the rays that hit
    nothing.  Groups are whatever the caller maps materials to (the integrator: how
    the surface scatters), so shading works on slices after a single sort.
    """
    index: np.ndarray
    miss: np.ndarray
    t: np.ndarray
    kind: np.ndarray
    prim: np.ndarray
    u: np.ndarray
    v: np.ndarray
    material: np.ndarray
    runs: dict
    groups: list
    kinds: set = frozenset(KINDS)       # the kinds that have hits (those of `runs`)


def check_rows(o, d) -> None:
    if o.ndim != 2 or o.shape[0] != 3 or d.shape != o.shape:
        raise ValueError(f"rays must be (3, N) rows (engine/core/vec.py), got {o.shape} and {d.shape}")


class Counters:
    """Per-worker ray counts and time spent inside intersection kernels (all of them, and
    the triangle accelerator's call alone: Embree, octree or brute force)."""

    def __init__(self):
        self.rays = {"camera": 0, "extension": 0, "shadow": 0}
        self.seconds_in_intersection = 0.0
        self.seconds_in_accelerator = 0.0
        self.nonfinite_samples = 0
        self.photons = {}            # caustic photon passes (engine/integrators/photons/caustics.py)
        self.photon_radii = {}       # their radius, by pass

    def merge(self, other: "Counters") -> None:
        for key, value in other.rays.items():
            self.rays[key] += value
        self.seconds_in_intersection += other.seconds_in_intersection
        self.seconds_in_accelerator += other.seconds_in_accelerator
        self.nonfinite_samples += other.nonfinite_samples
        for key, value in getattr(other, "photons", {}).items():
            self.photons[key] = self.photons.get(key, 0) + value
        self.photon_radii.update(getattr(other, "photon_radii", {}))


class SceneGeometry:
    def __init__(self, scene, accelerator: str = "embree", plan=None):
        """plan: the effect plan (engine/integrators/effects.py) that switches kernels on; None = every
        kernel whose primitives the scene has (tests of geometry alone)."""
        tris, tri_mats, tables = [], [], []
        for mesh in scene.meshes:
            if len(mesh.triangles):
                # vertices[triangles] as one take of rows (the same copy; fancy indexing with a
                # (T, 3) index: 3.0 -> 0.6 ms for 93k triangles)
                tris.append(mesh.vertices.take(mesh.triangles.reshape(-1), axis=0).reshape(-1, 3, 3))
                tri_mats.append(mesh.material_ids)
                tables.append(triangle_rows(mesh.vertices, mesh.triangles))
        self.triangles = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
        self.triangle_material = np.concatenate(tri_mats) if tri_mats else np.zeros(0, np.int64)
        # rows v0, v1 - v0, v2 - v0, the unit normal and the largest coordinate of each triangle,
        # computed as rows (engine/core/vec.py triangle_rows: the values of the (T, 3) formulas
        # np.cross, np.linalg.norm(axis=1), np.abs(...).max(axis=(1, 2)) bit for bit, faster)
        self.tri_v0, self.tri_e1, self.tri_e2, self.tri_scale = (
            (np.concatenate(part, axis=-1) for part in zip(*tables)) if tables
            else (np.zeros((3, 0)), np.zeros((3, 0)), np.zeros((3, 0)), np.zeros(0)))
        normal = cross_rows(self.tri_e1, self.tri_e2)
        self.tri_normal = normal / np.maximum(norm(normal), 1e-300)

        self.sphere_center = rows([s.center for s in scene.spheres])      # (3, S)
        self.sphere_radius = np.array([s.radius for s in scene.spheres], dtype=np.float64)
        self.sphere_material = np.array([s.material_id for s in scene.spheres], dtype=np.int64)

        backends = getattr(plan, "backends", {})       # kernel -> "numba" | "numpy" (engine/integrators/effects.py)
        self.quads = QuadSet(np.array([q.corners for q in scene.quads]).reshape(-1, 4, 3),
                             backend=backends.get("quads", "numpy"))
        self.quad_material = np.array([q.material_id for q in scene.quads], dtype=np.int64)

        self.intersect_sphere = sphere_kernel(backends.get("spheres", "numpy"))
        self.sphere_loops = sphere_loop_kernels(backends.get("spheres", "numpy"))    # compiled: all in one loop
        self.hits_jit = None            # the hit sort and triangle surfaces compiled (engine/geometry/hits_jit.py)
        if backends.get("wavefront", "numpy") == "numba":
            from . import hits_jit
            self.hits_jit = hits_jit

        def kernel(name, present):
            return bool(present) if plan is None else bool(plan.enabled[name])
        self.has_triangles = kernel("triangles", len(self.triangles))
        self.has_spheres = kernel("spheres", len(self.sphere_radius))
        self.has_quads = kernel("quads", self.quads.count)
        self.has_lights = plan is not None and bool(plan.enabled.get("area_lights"))
        self.lights = LightPolygons(scene.lights if self.has_lights else [], backend=backends.get("area_lights", "numpy"))
        # Smooth shading: interpolated corner normals, only when the plan says a scene has them.
        self.smooth = (SmoothNormals(scene.meshes) if self.has_triangles and kernel("smooth_normals",
                       has_smooth(scene.meshes)) else None)
        if self.smooth is not None and self.hits_jit is not None and self.triangles.dtype == np.float64:
            from . import shading_normals_jit         # its Phong normals and terminator lift in one loop each
            self.smooth.jit = shading_normals_jit

        # Material of (kind, prim) as one lookup: primitive_material[kind_base[kind] + prim];
        # light polygons have no material (slot 0: the caller groups them by kind).
        self.primitive_material = np.concatenate([
            np.zeros(1, np.int64), self.triangle_material.astype(np.int64),
            self.sphere_material, self.quad_material, np.zeros(self.lights.count, np.int64)])
        n_tri, n_sph, n_quad = len(self.triangle_material), len(self.sphere_material), len(self.quad_material)
        self.kind_base = np.array([1, 1, 1 + n_tri, 1 + n_tri + n_sph, 1 + n_tri + n_sph + n_quad],
                                  dtype=np.int64)                   # a miss (prim -1) -> slot 0
        start = time.perf_counter()
        self.accelerator = build_accelerator(accelerator, self.triangles) if self.has_triangles else None
        # Embree called on the rays' rows by a compiled loop (engine/geometry/accel/embree_jit.py)
        # instead of embreex on float32 copies; None: the accelerator's own intersect / occluded.
        self.accel_jit = None
        if (backends.get("wavefront", "numpy") == "numba" and self.accelerator is not None
                and self.accelerator.compiled_rows):
            from .accel import embree_jit
            self.accel_jit = embree_jit if embree_jit.bind() else None
        r = self.sphere_radius[:, None]
        self.sphere_tree = (BoxTree(*padded_boxes(self.sphere_center.T - r, self.sphere_center.T + r))
                            if self.has_spheres and len(r) > LOOP_MAX["spheres"] else None)
        self.quad_tree = (BoxTree(*padded_boxes(*self.quads.boxes()))
                          if self.has_quads and self.quads.count > LOOP_MAX["quads"] else None)
        self.light_tree = (BoxTree(*padded_boxes(*self.lights.boxes()))
                           if self.lights.count > LOOP_MAX["lights"] else None)
        self.build_seconds = time.perf_counter() - start

    # -- queries -----------------------------------------------------------------
    def intersect(self, o, d, counters: Counters, tmax=None, ray_kind=None):
        """Nearest hit of each ray (rows o, d): (t, kind, prim, u, v); t = +inf and kind =
        NONE on a miss.  ray_kind (N,) int8 (LightPolygons.RAY_KINDS) selects which Area
        lights each ray can see; None: all of them."""
        check_rows(o, d)
        n = o.shape[1]
        start = time.perf_counter()
        t = np.full(n, np.inf) if tmax is None else np.asarray(tmax, dtype=np.float64).copy()
        kind = np.zeros(n, dtype=np.int8)
        prim = np.full(n, -1, dtype=np.int64)
        u = v = np.zeros(n)
        if self.has_triangles:
            t0 = time.perf_counter()                        # the accelerator call only
            t, kind, prim, u, v = self.accelerator.nearest_rows(o, d, t, self.accel_jit)    # kind: TRIANGLE or NONE
            counters.seconds_in_accelerator += time.perf_counter() - t0
        if self.has_spheres and self.sphere_tree is None and self.sphere_loops is not None:
            t = self.sphere_loops[0](o, d, self.sphere_center, self.sphere_radius, t, kind, prim, SPHERE)
        elif self.has_spheres:
            t = self._nearest(SPHERE, self.sphere_tree, len(self.sphere_radius), self._sphere_test(o, d), o, d, t, kind,
                              prim)
        if self.has_quads and self.quad_tree is None and self.quads.loops is not None:    # compiled, as spheres
            t = self.quads.loops[0](self.quads, o, d, t, kind, prim, QUAD)
        elif self.has_quads:
            t = self._nearest(QUAD, self.quad_tree, self.quads.count, self._quad_test(o, d), o, d, t, kind, prim)
        sees = self.lights.rays_that_see_any(ray_kind) if self.lights.count else None
        if self.lights.count and sees is None:
            t = self._nearest(LIGHT, self.light_tree, self.lights.count, self._light_test(o, d, ray_kind), o, d,
                              t, kind, prim)
        elif self.lights.count and len(sees):            # only the rays some light is visible to
            o_s, d_s, kind_s, prim_s = o.take(sees, axis=1), d.take(sees, axis=1), kind.take(sees), prim.take(sees)
            test = self._light_test(o_s, d_s, ray_kind.take(sees))
            t[sees] = self._nearest(LIGHT, self.light_tree, self.lights.count, test, o_s, d_s, t.take(sees), kind_s,
                                    prim_s)
            kind[sees], prim[sees] = kind_s, prim_s
        kind[~np.isfinite(t)] = NONE
        if tmax is not None:
            t[kind == NONE] = np.inf
        counters.seconds_in_intersection += time.perf_counter() - start
        return t, kind, prim, u, v

    def nearest_hits(self, o, d, counters: Counters, material_group=None,
                     n_groups: int = 1, light_group: int = 0, ray_kind=None, forced_group=None) -> HitSet:
        """Nearest hits sorted by (material_group[material], kind); see HitSet.

        `material_group` maps material ids to 0 .. n_groups-1 (default: one group); rays with
        forced_group >= 0 go to that group instead; hits on Area lights form group `light_group`."""
        t, kind, prim, u, v = self.intersect(o, d, counters, ray_kind=ray_kind)
        kinds = len(KINDS)
        if self.hits_jit is not None:       # the same order, bounds and arrays in one counting sort
            order, bounds, t_h, kind_h, prim_h, u_h, v_h, material_h = self.hits_jit.sort_hits(
                t, kind, prim, u, v, self.primitive_material, self.kind_base, material_group, forced_group,
                light_group, self.lights.count > 0, n_groups)
            return self._hit_set(order, bounds, n_groups, t_h, kind_h, prim_h, u_h, v_h, material_h)
        material = self.primitive_material.take(prim + self.kind_base.take(kind))   # misses: ignored
        group = (np.zeros(len(kind), np.int8) if material_group is None
                 else material_group.take(material).astype(np.int8))
        if forced_group is not None:
            group = np.where(forced_group >= 0, forced_group, group).astype(np.int8)
        if self.lights.count:
            group = np.where(kind == LIGHT, np.int8(light_group), group)
        key = np.where(kind == NONE, 0, 1 + group * kinds + (kind - 1)).astype(np.int8)
        order = np.argsort(key, kind="stable")
        bounds = np.searchsorted(key.take(order), np.arange(2 + n_groups * kinds))
        index = order[bounds[1]:]
        return self._hit_set(order, bounds, n_groups, t.take(index), kind.take(index), prim.take(index),
                             u.take(index), v.take(index), material.take(index))

    @staticmethod
    def _hit_set(order, bounds, n_groups, t, kind, prim, u, v, material) -> HitSet:
        """The HitSet of rays `order` (misses first, then the hits sorted by key), `bounds` the first
        place of each key (0: miss, 1 + group x kinds + kind - 1), and the hits' arrays in order."""
        kinds = len(KINDS)
        first = int(bounds[1])
        miss, index = order[:first], order[first:]
        bounds = bounds.tolist()                # Python ints: the loop below costs ~10x less than on NumPy's
        runs = {}
        for g in range(n_groups):
            for k in KINDS:
                slot = 1 + g * kinds + (k - 1)
                if bounds[slot + 1] > bounds[slot]:
                    runs[(g, k)] = (bounds[slot] - first, bounds[slot + 1] - first)
        groups = [(bounds[1 + g * kinds] - first, bounds[1 + (g + 1) * kinds] - first) for g in range(n_groups)]
        return HitSet(index, miss, t, kind, prim, u, v, material, runs, groups, {k for _, k in runs})

    def occluded(self, o, d, tmax, counters: Counters):
        """True where something lies on the segment (0, tmax) of the ray (rows o, d)."""
        check_rows(o, d)
        start = time.perf_counter()
        blocked = np.zeros(o.shape[1], dtype=bool)
        if self.has_triangles:
            t0 = time.perf_counter()
            blocked |= self.accelerator.occluded_rows(o, d, tmax, self.accel_jit)
            counters.seconds_in_accelerator += time.perf_counter() - t0
        loops = self.has_spheres and self.sphere_tree is None and self.sphere_loops is not None
        if loops:            # compiled: every sphere in one loop per ray, on all rays (it skips the blocked ones)
            self.sphere_loops[1](o, d, self.sphere_center, self.sphere_radius, tmax, blocked)
        quad_loops = self.has_quads and self.quad_tree is None and self.quads.loops is not None
        if quad_loops:
            self.quads.loops[1](self.quads, o, d, tmax, blocked)
        if (self.has_spheres and not loops) or (self.has_quads and not quad_loops):
            rest = np.flatnonzero(~blocked)
            if len(rest) < len(blocked):
                o, d, tmax = o.take(rest, axis=1), d.take(rest, axis=1), tmax.take(rest)
            hit = np.zeros(len(rest), dtype=bool)
            for tree, count, test in ((self.sphere_tree, 0 if loops else len(self.sphere_radius), self._sphere_test(o, d)),
                                      (self.quad_tree, 0 if quad_loops else self.quads.count, self._quad_test(o, d))):
                if tree is None:
                    everyone = np.arange(len(rest))
                    for k in range(count):
                        hit |= test(everyone, k, tmax) < tmax
                else:
                    ray, k = tree.all_pairs(o, d, tmax)
                    bound = tmax.take(ray)
                    hit[ray[test(ray, k, bound) < bound]] = True
            blocked[rest] = hit
        counters.seconds_in_intersection += time.perf_counter() - start
        return blocked

    # -- the analytic kinds: one test per kind, on all rays for one primitive or on (ray, primitive) pairs
    @staticmethod
    def _nearest(kind_id, tree, count, test, o, d, t, kind, prim):
        """Fold the nearest hits of one analytic kind into (t, kind, prim): one primitive after the
        other (nearer replaces, so of equal distances the lowest number wins) without a tree (up to
        LOOP_MAX of them), else through their BoxTree, which gives the same hits
        (engine/geometry/shapes/box_tree.py)."""
        if tree is not None:
            t, best = tree.nearest(o, d, t, test)
            won = np.flatnonzero(best >= 0)
            kind[won], prim[won] = kind_id, best.take(won)
            return t
        everyone = np.arange(len(t))
        for k in range(count):
            tk = test(everyone, k, t)
            closer = tk < t
            t = np.where(closer, tk, t)
            kind[closer], prim[closer] = kind_id, k
        return t

    def _sphere_test(self, o, d):
        def test(ray, k, bound):
            if np.ndim(k) == 0:
                return self.intersect_sphere(o, d, self.sphere_center[:, k], self.sphere_radius[k], bound)
            return self.intersect_sphere(o.take(ray, axis=1), d.take(ray, axis=1), self.sphere_center.take(k, axis=1),
                                    self.sphere_radius.take(k), bound)
        return test

    def _quad_test(self, o, d):
        def test(ray, k, bound):
            if np.ndim(k) == 0:
                return self.quads.intersect_one(k, o, d, bound)
            return self.quads.intersect_pairs(k, o.take(ray, axis=1), d.take(ray, axis=1), bound)
        return test

    def _light_test(self, o, d, ray_kind):
        def test(ray, k, bound):
            if np.ndim(k) == 0:                              # the rays of the kinds light k is visible to
                sees = self.lights.rays_that_see(k, ray_kind)
                if sees is None:
                    return self.lights.intersect_one(k, o, d, bound)
                tl = np.full(o.shape[1], np.inf)
                if len(sees):
                    tl[sees] = self.lights.intersect_one(k, o.take(sees, axis=1), d.take(sees, axis=1),
                                                         bound.take(sees))
                return tl
            return self.lights.intersect_pairs(k, o.take(ray, axis=1), d.take(ray, axis=1), bound,
                                               None if ray_kind is None else ray_kind.take(ray))
        return test

    def surface(self, o, d, hits: HitSet, rays_order: bool = False) -> SurfaceHits:
        """Shading data for the hit rays; rows d in hits.index order, o too or, with rays_order, in
        the rays' order (hit j's origin is o[:, hits.index[j]])."""
        if self.hits_jit is not None and self.smooth is None and LIGHT not in hits.kinds:
            # every hit in one compiled loop, the same numbers as the runs below, and the facing normal
            quads = self.quads
            point, normal, offset, facing = self.hits_jit.surfaces(
                o, d, hits.t, hits.kind, hits.prim, hits.u, hits.v, self.tri_v0, self.tri_e1, self.tri_e2,
                self.tri_normal, self.tri_scale, TRIANGLE_OFFSET, self.sphere_center, self.sphere_radius, EPS64,
                quads.normal_rows, quads.v00_rows, quads.scale, hits.index if rays_order else None)
            return SurfaceHits(point, normal, hits.material, offset, facing=facing)
        if rays_order:
            o = o.take(hits.index, axis=1)
        parts, shading = [], []
        for (_, k), (a, b) in hits.runs.items():             # in index order (nearest_hits)
            prim = hits.prim[a:b]
            if k == TRIANGLE:
                pt, nrm, off = self._triangle_surface(prim, hits.u[a:b], hits.v[a:b])
                if self.smooth is not None:
                    shading.append((len(parts), self.smooth.shading(prim, hits.u[a:b], hits.v[a:b], nrm)))
            elif k == SPHERE and self.hits_jit is not None:       # the same operations in one loop
                pt, nrm, off = self.hits_jit.sphere_surface(o, d, hits.t, a, prim, self.sphere_center,
                                                            self.sphere_radius, EPS64)
            elif k == SPHERE:
                pt, nrm, off = surface_point(o[:, a:b], d[:, a:b], hits.t[a:b],
                                             self.sphere_center.take(prim, axis=1), self.sphere_radius.take(prim))
            elif k == LIGHT:
                pt, nrm, off = self.lights.surface(o[:, a:b], d[:, a:b], hits.t[a:b], prim)
            else:
                pt, nrm, off = self.quads.surface(o[:, a:b], d[:, a:b], hits.t[a:b], prim)
            parts.append((pt, nrm, off))
        if len(parts) == 1:
            pt, nrm, off = parts[0]
            return SurfaceHits(pt, nrm, hits.material, off, shading[0][1] if shading else None)
        if not parts:
            empty = np.zeros((3, 0))
            return SurfaceHits(empty, empty, hits.material, np.zeros(0))
        points, normals, offsets = zip(*parts)
        point, normal, offset = (np.concatenate(points, axis=1), np.concatenate(normals, axis=1),
                                 np.concatenate(offsets))
        if shading:                         # the smooth normals replace those triangles' columns
            per_part = list(normals)
            for i, nrm_s in shading:
                per_part[i] = nrm_s
            return SurfaceHits(point, normal, hits.material, offset, np.concatenate(per_part, axis=1))
        return SurfaceHits(point, normal, hits.material, offset)

    def terminator_lift(self, hits: HitSet, span: slice, facing):
        """Shadow-terminator lift of the hits in `span` (engine/geometry/shading_normals.py): (lift rows,
        cutoff) for their shadow rays, or None when none of them is on a smooth triangle."""
        if self.smooth is None:
            return None
        if self.smooth.jit is not None:     # the same numbers in one loop
            return self.smooth.jit.terminator_lift(hits.kind, hits.prim, hits.u, hits.v, facing, span, self.smooth.index,
                                                   self.smooth.cutoff, self.smooth.corners, self.triangles)
        tri = np.flatnonzero(hits.kind[span] == TRIANGLE)
        if not len(tri):
            return None
        m = span.stop - span.start
        lift, cutoff = np.zeros((3, m)), np.zeros(m)
        lift[:, tri], cutoff[tri] = self.smooth.terminator_lift(
            hits.prim[span].take(tri), hits.u[span].take(tri), hits.v[span].take(tri),
            facing[:, span].take(tri, axis=1), self.triangles)
        return (lift, cutoff) if (cutoff > 0.0).any() else None

    def _triangle_surface(self, prim, u, v):
        """(point, normal, offset) of triangle hits."""
        # Barycentric interpolation in float64 puts the point on the triangle's plane
        # (pbrt): the float32 error of o + t d would be along the ray instead.
        if self.hits_jit is not None:       # the same operations in one loop (engine/geometry/hits_jit.py)
            return self.hits_jit.triangle_surface(prim, u, v, self.tri_v0, self.tri_e1, self.tri_e2,
                                                  self.tri_normal, self.tri_scale, TRIANGLE_OFFSET)
        point = (self.tri_v0.take(prim, axis=1) + u * self.tri_e1.take(prim, axis=1)
                 + v * self.tri_e2.take(prim, axis=1))
        offset = TRIANGLE_OFFSET * np.maximum(max_abs3(point), self.tri_scale.take(prim))
        return point, self.tri_normal.take(prim, axis=1), offset
