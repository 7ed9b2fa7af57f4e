"""The first step of the light set (engine/lights/light_set.py): every emitter of a scene, gathered
per kind, and which light each emissive primitive is.

* Emissive mesh triangles, in the order SceneGeometry numbers them.  Under solid-angle sampling a
  quad that Blender split into two triangles of one material becomes one parallelogram light
  (spherical rectangle sampling, engine/lights/parallelograms.py); the others are triangle lights.
* Emissive quads and Blender Area lights: parallelograms where they are one, polygons otherwise
  (disks, ellipses, other quads).  An Area light whose Diffuse visibility is off lights no diffuse
  surface (as in Cycles): it is left out; rays of the kinds it is visible to still see it.
* Emissive spheres; point and spot lights (those that light diffuse surfaces).
* At infinity: the sun lights that light diffuse surfaces, and the world when it is a light: the
  image world (engine/lights/environment.py EnvironmentLight) when the scene has one that lights,
  else the constant background (engine/lights/distant.py WorldLight).

The kinds are built in a fixed order (parallelograms, triangles, spheres, polygons, points; then
suns and the world), each from its emitters in the order they were found: the light numbers, and
with them the power pmf and the light tree, do not depend on anything else.
"""
from __future__ import annotations

import numpy as np

from .distant import SunLights, WorldLight
from .environment import EnvironmentLight, EnvironmentMap
from .parallelograms import Parallelograms
from .points import PointLights
from .polygons import Polygons
from .spheres import Spheres
from .triangles import Triangles

PARALLELOGRAM_TOLERANCE = 1e-9       # |v00 + v11 - v10 - v01| relative to the quad's size


def parallelogram_pairs(vertices, triangles, material_ids):
    """Consecutive triangles of one material that form a parallelogram (a quad as Blender
    triangulates it): returns (first triangle of each pair, corner v0, edges e1, e2), the
    edges oriented like the first triangle's normal.  Such a pair is sampled as one
    parallelogram light (spherical rectangle) instead of two spherical triangles."""
    t = np.asarray(triangles, dtype=np.int64)
    if len(t) < 2:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3))
    v = np.asarray(vertices, dtype=np.float64)
    a, b = t[:-1], t[1:]
    in_b = (a[:, :, None] == b[:, None, :]).any(axis=2)        # which corners of a are in b
    in_a = (b[:, :, None] == a[:, None, :]).any(axis=2)
    rows_ = np.arange(len(a))
    candidate = (in_b.sum(axis=1) == 2) & (material_ids[:-1] == material_ids[1:])
    p = v[a[rows_, np.argmin(in_b, axis=1)]]                   # a's corner not shared
    q = v[b[rows_, np.argmin(in_a, axis=1)]]                   # b's corner not shared
    shared = np.sort(np.where(in_b, a, -1), axis=1)[:, 1:]     # a's two shared corners
    s1, s2 = v[shared[:, 0]], v[shared[:, 1]]
    size = np.maximum(np.abs(s1 - p).max(axis=1), np.abs(s2 - p).max(axis=1))
    candidate &= np.abs(p + q - s1 - s2).max(axis=1) <= PARALLELOGRAM_TOLERANCE * np.maximum(size, 1e-300)
    first, taken = [], -2
    for i in np.flatnonzero(candidate):                          # no triangle in two pairs
        if i > taken + 1:
            first.append(i)
            taken = i
    first = np.array(first, dtype=np.int64)
    e1, e2 = s1[first] - p[first], s2[first] - p[first]
    normal = np.cross(v[a[first, 1]] - v[a[first, 0]], v[a[first, 2]] - v[a[first, 0]])
    flip = np.einsum("ij,ij->i", np.cross(e1, e2), normal) < 0
    e1[flip], e2[flip] = s2[first][flip] - p[first][flip], s1[first][flip] - p[first][flip]
    return first, p[first], e1, e2


def is_parallelogram(c: np.ndarray) -> bool:
    return bool(parallelograms_among(np.asarray(c, dtype=np.float64)[None])[0])


def parallelograms_among(q: np.ndarray) -> np.ndarray:
    """(K,) bool: which of the quadrilaterals q (K, 4, 3) are parallelograms."""
    size = np.abs(q - q[:, :1]).max(axis=(1, 2), initial=0.0)
    gap = np.abs(q[:, 0] + q[:, 2] - q[:, 1] - q[:, 3]).max(axis=1, initial=0.0)
    return gap <= PARALLELOGRAM_TOLERANCE * np.maximum(size, 1e-300)


def scene_radius(scene) -> float:
    """Radius of a sphere about the origin that holds every primitive of the scene."""
    extent = [0.0]
    extent += [float(np.abs(np.asarray(m.vertices)).max()) for m in scene.meshes if len(m.vertices)]
    extent += [float(np.abs(np.asarray(s.center)).max() + s.radius) for s in scene.spheres]
    extent += [float(np.abs(np.asarray(q.corners)).max()) for q in scene.quads]
    return float(np.sqrt(3.0) * max(extent))


class Collected:
    """The emitting surfaces of one kind as they are found.  `add` returns their numbers in the
    kind; `build` makes the kind (None without emitters).  reachable: whether a diffuse bounce ray
    can reach each light (MIS needs both strategies)."""

    def __init__(self, make):
        self.make = make          # (parts, radiance (K, 3), one_sided (K,)) -> the kind
        self.parts, self.radiance, self.one_sided, self.reachable, self.count = [], [], [], [], 0
        self.kind = None

    def add(self, data, radiance, one_sided, reachable=True):
        """Emitters of one radiance and flags each, or (arrays) of one each."""
        n = len(data[0]) if isinstance(data, tuple) else len(data)
        self.parts.append(data)
        self.radiance.append(np.broadcast_to(np.asarray(radiance, dtype=np.float64), (n, 3)))
        self.one_sided.append(np.broadcast_to(np.asarray(one_sided, dtype=bool), (n,)))
        self.reachable.append(np.broadcast_to(np.asarray(reachable, dtype=bool), (n,)))
        self.count += n
        return np.arange(self.count - n, self.count)

    def build(self):
        if self.count:
            self.kind = self.make(self.parts, np.concatenate(self.radiance), np.concatenate(self.one_sided))
        return self.kind


def _columns(parts, columns):
    return [np.concatenate([p[i] for p in parts]) for i in range(columns)]


class SceneEmitters:
    """The emitters of `scene` per kind (see the module's docstring).  After the light set has
    numbered the kinds (their `first`), `light_of_*` give the light of each primitive (-1: none)."""

    def __init__(self, scene, solid_angle: bool, lamps_hittable: bool, world: bool):
        mats = scene.materials
        self.emission = np.array([m.emission for m in mats], dtype=np.float64).reshape(-1, 3)
        self.emissive = self.emission.max(axis=1) > 0
        self.parallelograms = Collected(lambda parts, le, one: Parallelograms(*_columns(parts, 3), le, one))
        self.triangles = Collected(lambda parts, le, one: Triangles(*_columns(parts, 3), le, one))
        self.spheres = Collected(lambda parts, le, one: Spheres(*_columns(parts, 2), le, one))
        self.polygons = Collected(lambda parts, le, one: Polygons([c for part in parts for c in part], le, one))
        self._mesh_triangles(scene, solid_angle)
        quads = [q for q in scene.quads if self.emissive[q.material_id]]
        self.quad_refs = self._flat([q.corners for q in quads], [self.emission[q.material_id] for q in quads],
                                    [False] * len(quads), [True] * len(quads),
                                    [self.emissive[q.material_id] for q in scene.quads])
        lights = [light for light in scene.lights if light.lights_diffuse]
        self.area_light_refs = self._flat([light.vertices for light in lights], [light.radiance for light in lights],
                                          [not light.two_sided for light in lights],
                                          [lamps_hittable and light.visible_diffuse for light in lights],
                                          [light.lights_diffuse for light in scene.lights])
        self.sphere_refs = [(self.spheres, int(self.spheres.add(([s.center], [s.radius]),
                                                                  self.emission[s.material_id], False)[0]))
                            if self.emissive[s.material_id] else None for s in scene.spheres]
        surfaces = [self.parallelograms, self.triangles, self.spheres, self.polygons]
        self.surface_kinds = [kind for kind in (c.build() for c in surfaces) if kind is not None]
        self.surface_reachable = [np.concatenate(c.reachable) for c in surfaces if c.count]
        points = [p for p in scene.points if p.lights_diffuse]        # Diffuse visibility off: no light
        self.points = PointLights(points) if points else None
        suns = [s for s in scene.suns if s.lights_diffuse]
        # The image world (None without one): what escaping rays see, and a light when it lights.
        self.environment = EnvironmentMap.of(scene) if getattr(scene, "environment", None) is not None else None
        image = self.environment is not None and self.environment.lights
        constant = max(scene.background) > 0 and not (self.environment is not None and self.environment.env.lighting)
        sky = world and (image or constant)
        radius = scene_radius(scene) if suns or sky else 0.0
        self.suns = SunLights(suns, radius) if suns else None
        self.world = (EnvironmentLight(self.environment, radius) if image else
                      WorldLight(scene.background, radius)) if sky else None

    def _mesh_triangles(self, scene, solid_angle):
        """Per mesh with triangles: (its triangles' lights among the parallelograms, among the
        triangles), -1 where a triangle is no light there."""
        self.mesh_refs = []
        for mesh in scene.meshes:
            if not len(mesh.triangles):
                continue
            ids = np.asarray(mesh.material_ids, dtype=np.int64)
            as_para = np.full(len(ids), -1, dtype=np.int64)
            as_tri = np.full(len(ids), -1, dtype=np.int64)
            sel = np.flatnonzero(self.emissive[ids])
            if len(sel):
                tris = np.asarray(mesh.triangles)[sel]
                single = np.ones(len(sel), dtype=bool)
                if solid_angle:                                     # quads as parallelograms
                    first, v0, e1, e2 = parallelogram_pairs(mesh.vertices, tris, ids[sel])
                    if len(first):
                        lights = self.parallelograms.add((v0, e1, e2), self.emission[ids[sel[first]]], False)
                        as_para[sel[first]] = as_para[sel[first + 1]] = lights
                        single[first] = single[first + 1] = False
                v = np.asarray(mesh.vertices, dtype=np.float64)[tris[single]]
                as_tri[sel[single]] = self.triangles.add((v[:, 0], v[:, 1], v[:, 2]), self.emission[ids[sel[single]]],
                                                         False)
            self.mesh_refs.append((as_para, as_tri))

    def _flat(self, corners, radiance, one_sided, reachable, taken):
        """Planar emitters, each a parallelogram or else a polygon, added to those in order (one call
        per kind: 100k Area lights in well under a second): per primitive of the scene (`taken` says
        which of them `corners` lists) the (Collected it went to, its number there), or None."""
        c = [np.asarray(x, dtype=np.float64) for x in corners]
        radiance = np.array(radiance, dtype=np.float64).reshape(-1, 3)
        one_sided, reachable = np.array(one_sided, dtype=bool), np.array(reachable, dtype=bool)
        four = np.flatnonzero([len(x) == 4 for x in c])
        para = np.zeros(len(c), dtype=bool)
        if len(four):
            q = np.array([c[i] for i in four])
            para[four] = parallelograms_among(q)
        refs = [None] * len(c)
        for into, sel in ((self.parallelograms, np.flatnonzero(para)), (self.polygons, np.flatnonzero(~para))):
            if not len(sel):
                continue
            if into is self.parallelograms:
                q = np.array([c[i] for i in sel])
                data = (q[:, 0], q[:, 1] - q[:, 0], q[:, 3] - q[:, 0])
            else:
                data = [c[i] for i in sel]
            numbers = into.add(data, radiance[sel], one_sided[sel], reachable[sel])
            for i, k in zip(sel.tolist(), numbers.tolist()):
                refs[i] = (into, k)
        found = iter(refs)
        return [next(found) if t else None for t in taken]

    # -- after the light set numbered the kinds -------------------------------------------
    def local_kinds(self) -> list:
        """The kinds at finite distance, in light-number order."""
        return self.surface_kinds + ([self.points] if self.points is not None else [])

    def distant_kinds(self) -> list:
        return [k for k in (self.suns, self.world) if k is not None]

    def local_reachable(self) -> np.ndarray:
        """Per light at finite distance: can a diffuse bounce ray reach it?  Point lights: never."""
        parts = self.surface_reachable + ([np.zeros(self.points.count, bool)] if self.points is not None else [])
        return np.concatenate(parts) if parts else np.zeros(0, bool)

    def light_of_triangles(self) -> np.ndarray:
        if not self.mesh_refs:
            return np.zeros(0, np.int64)
        para = self.parallelograms.kind.first if self.parallelograms.kind is not None else 0
        tri = self.triangles.kind.first if self.triangles.kind is not None else 0
        return np.concatenate([np.where(p >= 0, p + para, np.where(t >= 0, t + tri, -1)) for p, t in self.mesh_refs])

    @staticmethod
    def light_of(refs) -> np.ndarray:
        return np.array([-1 if ref is None else ref[0].kind.first + ref[1] for ref in refs], dtype=np.int64)
