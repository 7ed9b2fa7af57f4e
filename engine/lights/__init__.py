"""Lights: every emitter of a scene, how a shading point picks one, and how it samples it.

Emitter kinds (one module each, all with `sample(x, idx, u1, u2, solid_angle)` and
`pdf(x, idx, point, solid_angle)` returning densities per unit solid angle at x):

* parallelograms.py: emissive quads that are parallelograms and 4-corner Area lights
  (spherical rectangles, Urena et al. 2013, for rectangles);
* triangles.py: emissive mesh triangles (spherical triangles, Arvo 1995);
* spheres.py: emissive implicit spheres (cone from outside, area from inside);
* polygons.py: disk/ellipse Area lights and quads that are not parallelograms (area).

`LightSampler` numbers the lights kind after kind, picks one with a selection pmf
(selection.py: by power for the report's estimator, a light tree otherwise), and returns
light samples whose `pdf` is P(k | x, n) x p_w, the density of the direction x -> y.  It
also maps every emissive primitive to its light (`triangle_light`, `sphere_light`,
`quad_light`, `area_light_light`), so an emitter found by BSDF sampling knows the
density the light sampler had for it (MIS).

Emissive surfaces emit from both sides, as Cycles mesh lights; AreaLights (Blender Area
lights) from their front only unless marked two-sided.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.vec import dot, max_abs3, rows
from .parallelograms import Parallelograms
from .polygons import Polygons
from .selection import LightTree, PowerSelection
from .spheres import Spheres
from .distant import DistantLights
from .points import PointLights
from .seen import SeenLamps
from .triangles import Triangles

# Shadow-ray end points are pulled off the light by this relative amount (as the
# triangle spawn offset) so the ray never reports the light itself as occluder.
LIGHT_OFFSET = 2.0 ** -20
PARALLELOGRAM_TOLERANCE = 1e-9       # |v00 + v11 - v10 - v01| relative to the quad's size
PAIRED = 1 << 40                     # marks a mesh triangle whose light is a parallelogram pair


@dataclass
class LightSample:
    point: np.ndarray      # (3, N) on the light (the world: one unit along `direction`)
    direction: np.ndarray  # (3, N) unit direction from the receiver to the point
    distance: np.ndarray   # (N,) to the point; inf for the world
    normal: np.ndarray     # (3, N) unit normal of the light at the point (the world: -direction)
    radiance: np.ndarray   # (3, N) emitted radiance Le
    pdf: np.ndarray        # (N,) P(k | x, n) * p_w(x -> point); 0: no sample
    light: np.ndarray      # (N,) light index
    offset: np.ndarray     # (N,) distance along the normal that clears the light
    one_sided: np.ndarray  # (N,) bool: emits only towards the side its normal faces


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
    size = np.abs(c - c[0]).max()
    return bool(np.abs(c[0] + c[2] - c[1] - c[3]).max() <= PARALLELOGRAM_TOLERANCE * max(size, 1e-300))


class _Gather:
    """Emitters of one kind as they are found; `add` returns their light numbers in the kind."""

    def __init__(self):
        self.parts, self.radiance, self.one_sided, self.count = [], [], [], 0

    def add(self, data, radiance, one_sided):
        n = len(data[0]) if isinstance(data, tuple) else len(data)
        self.parts.append(data)
        self.radiance.append(np.broadcast_to(np.asarray(radiance, dtype=np.float64), (n, 3)))
        self.one_sided.append(np.full(n, bool(one_sided)))
        self.count += n
        return np.arange(self.count - n, self.count)


class SpotFalloff:
    """Scales the radiance of light samples from spot lights (global light numbers `first` ...
    of the point-light kind) by their cone's falloff towards the receiver."""

    def __init__(self, points, first: int):
        self.points, self.first = points, first

    def falloff(self, light, direction, radiance):
        """`radiance` (the caller's own copy) scaled in place where the light is a spot."""
        local = light - self.first
        sel = np.flatnonzero((local >= 0) & (local < self.points.count))
        if not len(sel):
            return radiance
        radiance[:, sel] *= self.points.spot_factor(local.take(sel), -direction.take(sel, axis=1))
        return radiance


class LightSampler:
    """All emitters of a scene.  solid_angle: sample each light by solid angle where stable
    (else by area, as eq. 2.11); spatial: pick lights with the light tree (else by power);
    lamps_hittable: rays can reach Area lights (the geometry tests them); world: the constant
    background is a light too.  Point lights are local lights; sun lights and the world are
    lights at infinity (engine/lights/distant.py), numbered after the local ones."""

    DISTANT_SHARE = (0.1, 0.9)        # bounds of the suns' and world's selection probability beside lamps

    def __init__(self, scene, solid_angle: bool = True, spatial: bool = True, lamps_hittable: bool = False,
                 world: bool = False):
        self.solid_angle = solid_angle
        mats = scene.materials
        emission = np.array([m.emission for m in mats], dtype=np.float64).reshape(-1, 3)
        emissive = emission.max(axis=1) > 0
        para, tri, sph, poly = _Gather(), _Gather(), _Gather(), _Gather()

        # Mesh triangles, in the order SceneGeometry numbers them.
        tri_local, n_tri = [], 0
        for mesh in scene.meshes:
            if not len(mesh.triangles):
                continue
            ids = np.asarray(mesh.material_ids, dtype=np.int64)
            local = np.full(len(ids), -1, dtype=np.int64)        # light of each triangle
            sel = np.flatnonzero(emissive[ids])
            if len(sel):
                tris = np.asarray(mesh.triangles)[sel]
                single = np.ones(len(sel), dtype=bool)
                if solid_angle:                                     # quads as parallelograms
                    first, v0, e1, e2 = parallelogram_pairs(mesh.vertices, tris, ids[sel])
                    if len(first):
                        lights = para.add((v0, e1, e2), emission[ids[sel[first]]], False)
                        local[sel[first]] = local[sel[first + 1]] = PAIRED + lights
                        single[first] = single[first + 1] = False
                v = np.asarray(mesh.vertices, dtype=np.float64)[tris[single]]
                local[sel[single]] = tri.add((v[:, 0], v[:, 1], v[:, 2]), emission[ids[sel[single]]], False)
            tri_local.append(local)
            n_tri += len(ids)

        def add_flat(corners, radiance, one_sided):
            c = np.asarray(corners, dtype=np.float64)
            if len(c) == 4 and is_parallelogram(c):
                return ("para", int(para.add((c[None, 0], c[None, 1] - c[0], c[None, 3] - c[0]), radiance,
                                             one_sided)[0]))
            return ("poly", int(poly.add([c], radiance, one_sided)[0]))

        quad_ref = [add_flat(q.corners, emission[q.material_id], False) if emissive[q.material_id] else None
                    for q in scene.quads]
        # An Area light whose Diffuse visibility is off lights no diffuse surface (as in Cycles):
        # the light sampler leaves it out; rays of the kinds it is visible to still see it.
        light_ref = [add_flat(light.vertices, light.radiance, not light.two_sided) if light.lights_diffuse
                     else None for light in scene.lights]
        sphere_ref = [("sph", int(sph.add(([s.center], [s.radius]), emission[s.material_id], False)[0]))
                      if emissive[s.material_id] else None for s in scene.spheres]

        def stack(gather, columns):
            return [np.concatenate([p[i] for p in gather.parts]) for i in range(columns)]
        self.kinds = []
        if para.count:
            self.kinds.append(("para", Parallelograms(*stack(para, 3)), para))
        if tri.count:
            self.kinds.append(("tri", Triangles(*stack(tri, 3)), tri))
        if sph.count:
            self.kinds.append(("sph", Spheres(*stack(sph, 2)), sph))
        if poly.count:
            self.kinds.append(("poly", Polygons([c for part in poly.parts for c in part]), poly))
        points = [p for p in scene.points if p.lights_diffuse]        # Diffuse visibility off: no light
        suns = [s for s in scene.suns if s.lights_diffuse]
        if points:
            pts = PointLights(points)
            gather_pts = _Gather()
            gather_pts.add(points, pts.radiance_rows.T, False)
            self.kinds.append(("pt", pts, gather_pts))
        base, start = {}, 0
        for name, kind, gather in self.kinds:
            base[name] = start
            start += kind.count
        self.spots = SpotFalloff(self.kinds[-1][1], base["pt"]) if points and len(pts.spots) else None
        self.count_all = start
        self.kind_of = np.concatenate([np.full(k.count, i) for i, (_, k, _) in enumerate(self.kinds)]
                                      ) if self.kinds else np.zeros(0, np.int64)
        self.local = np.concatenate([np.arange(k.count) for _, k, _ in self.kinds]) if self.kinds \
            else np.zeros(0, np.int64)
        self.radiance = rows(np.concatenate([np.concatenate(g.radiance) for _, _, g in self.kinds])
                             if self.kinds else np.zeros((0, 3)))
        self.one_sided = (np.concatenate([np.concatenate(g.one_sided) for _, _, g in self.kinds])
                          if self.kinds else np.zeros(0, bool))
        self.any_one_sided = bool(self.one_sided.any())

        def glob(ref):
            return -1 if ref is None else base[ref[0]] + ref[1]
        tri_base, para_base = base.get("tri", 0), base.get("para", 0)
        self.triangle_light = (np.concatenate([np.where(t >= PAIRED, t - PAIRED + para_base,
                                                        np.where(t >= 0, t + tri_base, -1)) for t in tri_local])
                               if tri_local else np.zeros(0, np.int64))
        self.quad_light = np.array([glob(r) for r in quad_ref], dtype=np.int64)
        self.area_light_light = np.array([glob(r) for r in light_ref], dtype=np.int64)
        self.sphere_light = np.array([glob(r) for r in sphere_ref], dtype=np.int64)
        # Whether a diffuse bounce ray can reach each light (MIS needs both strategies): emissive
        # surfaces always; Area lights when rays test them and their diffuse visibility is on.
        self.bsdf_reachable = np.ones(self.count_all, dtype=bool)
        for light, ref in zip(scene.lights, light_ref):
            if ref is not None:
                self.bsdf_reachable[glob(ref)] = lamps_hittable and light.visible_diffuse
        if points:                                                 # shadow rays only
            self.bsdf_reachable[base["pt"]:base["pt"] + len(points)] = False

        # Per light: area, the report's power (area x mean radiance) and bounds for the tree.
        area = np.concatenate([k.area for _, k, _ in self.kinds]) if self.kinds else np.zeros(0)
        mean_le = self.radiance.mean(axis=0)
        self.area = area
        self.report_power = area * mean_le
        sides = np.where(self.one_sided, 1.0, 2.0)
        self.power = np.pi * area * mean_le * sides               # emitted flux
        if points:                                                 # flux 4 pi I (the report: flux / pi)
            span = slice(base["pt"], base["pt"] + len(points))
            self.power[span] = self.kinds[-1][1].flux
            self.report_power[span] = self.power[span] / np.pi
        self.count = int((self.report_power > 0).sum())
        self.total_power = float(self.report_power.sum())
        if spatial and self.count_all > 1:
            center, radius, axis, cos_o = self._bounds()
            self.selection = LightTree(center, radius, axis, cos_o, self.power, self.power)
        else:
            self.selection = PowerSelection(self.report_power if self.count_all else np.ones(0))
        self.uses_tree = isinstance(self.selection, LightTree)
        # Lights at infinity (suns, and the world under the mis / solid-angle estimators) are
        # picked with probability `distant_share`, the lamps and emissive surfaces share the rest.
        self.distant, self.distant_share = None, 0.0
        if suns or (world and max(scene.background) > 0):
            self.distant = DistantLights(suns, scene.background if world else (0.0, 0.0, 0.0),
                                         scene_radius(scene))
            lamps, far = float(self.power.sum()), float(self.distant.power.sum())
            self.distant_share = 1.0 if lamps <= 0 else float(np.clip(far / (far + lamps), *self.DISTANT_SHARE))
            self.radiance = np.concatenate([self.radiance, self.distant.radiance], axis=1)
            self.one_sided = np.append(self.one_sided, np.zeros(self.distant.count, bool))
            reach = np.zeros(self.distant.count, bool)
            if self.distant.world_slot is not None:
                reach[self.distant.world_slot] = True              # escaping bounce rays reach the world
            self.bsdf_reachable = np.append(self.bsdf_reachable, reach)
            self.count += int((self.distant.power > 0).sum())
        self.world = None if self.distant is None or self.distant.world_slot is None else self.distant
        self.seen = SeenLamps.of(scene)        # round lamps and suns that mirror and glass rays meet

    def _bounds(self):
        """(centre (K,3), radius, normal axis (K,3), cos of the normal cone) of every light."""
        center, radius, axis, cos_o = [], [], [], []
        for name, kind, gather in self.kinds:
            center.append(kind.center.T)
            radius.append(kind.radius)
            if name in ("sph", "pt"):
                axis.append(np.tile([0.0, 0.0, 1.0], (kind.count, 1)))
                cos_o.append(np.full(kind.count, -1.0))              # normals in every direction
            else:
                axis.append(kind.normal.T)
                one_sided = np.concatenate(gather.one_sided)
                cos_o.append(np.where(one_sided, 1.0, -1.0))         # two-sided: either face
        return np.concatenate(center), np.concatenate(radius), np.concatenate(axis), np.concatenate(cos_o)

    # -- sampling --------------------------------------------------------------------------
    def sample(self, x, n, u_pick, u1, u2) -> LightSample:
        """One light sample per receiver x with facing normal n (rows)."""
        m = len(u_pick)
        q = self.distant_share
        far = u_pick < q
        light = np.empty(m, dtype=np.int64)
        point, normal, pdf = np.empty((3, m)), np.empty((3, m)), np.zeros(m)
        local = np.flatnonzero(~far) if q > 0 else None
        if local is None or len(local) == m:
            point, normal, pdf, light = self._sample_local(x, n, u_pick if q == 0 else (u_pick - q) / (1 - q), u1, u2)
        elif len(local):
            p, nrm, pd, lt = self._sample_local(x.take(local, axis=1), n.take(local, axis=1),
                                                (u_pick.take(local) - q) / (1.0 - q), u1.take(local), u2.take(local))
            point[:, local], normal[:, local], pdf[local], light[local] = p, nrm, pd, lt
        pdf = pdf * (1.0 - q)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):     # unused samples (pdf 0)
            w = point - x
            distance = np.sqrt(dot(w, w))
            direction = w / distance
        if q > 0 and far.any():
            sky = np.flatnonzero(far)
            normal = np.array(normal)                 # a kind may hand back a broadcast view
            d, pd, slot = self.distant.sample(n.take(sky, axis=1), u_pick.take(sky) / q, u1.take(sky), u2.take(sky))
            direction[:, sky], pdf[sky], distance[sky], light[sky] = d, q * pd, np.inf, self.count_all + slot
            point[:, sky], normal[:, sky] = x.take(sky, axis=1) + d, -d
        radiance = self.radiance.take(light, axis=1)
        if self.spots is not None:                                 # spot lights: the cone's falloff
            radiance = self.spots.falloff(light, direction, radiance)
        return LightSample(point, direction, distance, normal, radiance, pdf, light,
                           LIGHT_OFFSET * max_abs3(point), self.one_sided.take(light))

    def _sample_local(self, x, n, u_pick, u1, u2):
        """(point, normal, P(k) p_w, light) from the lamps and emissive surfaces."""
        light, pmf = self.selection.sample(x, n, u_pick)
        m = len(u_pick)
        if len(self.kinds) == 1:
            point, normal, pdf = self.kinds[0][1].sample(x, light, u1, u2, self.solid_angle)
        else:
            point, normal, pdf = np.empty((3, m)), np.empty((3, m)), np.empty(m)
            kind_of = self.kind_of.take(light)
            for i, (_, kind, _) in enumerate(self.kinds):
                sel = np.flatnonzero(kind_of == i)
                if len(sel):
                    p, nrm, pd = kind.sample(x.take(sel, axis=1), self.local.take(light.take(sel)),
                                             u1.take(sel), u2.take(sel), self.solid_angle)
                    point[:, sel], normal[:, sel], pdf[sel] = p, nrm, pd
        return point, normal, pdf * pmf, light

    def pdf(self, x, n, light, point) -> np.ndarray:
        """P(k | x, n) * p_w of the direction from x to `point` on lamp or emissive surface k: the
        density with which `sample` at (x, n) produces that direction (MIS at an emission hit)."""
        pdf = np.empty(len(light))
        if len(self.kinds) == 1:
            pdf[:] = self.kinds[0][1].pdf(x, light, point, self.solid_angle)
        else:
            kind_of = self.kind_of.take(light)
            for i, (_, kind, _) in enumerate(self.kinds):
                sel = np.flatnonzero(kind_of == i)
                if len(sel):
                    pdf[sel] = kind.pdf(x.take(sel, axis=1), self.local.take(light.take(sel)),
                                        point.take(sel, axis=1), self.solid_angle)
        return pdf * self.selection.pmf(x, n, light) * (1.0 - self.distant_share)

    def world_pdf(self, n, d) -> np.ndarray:
        """Density with which `sample` at a receiver with facing normal n produces the world
        direction d (MIS for a bounce ray that escapes)."""
        return self.distant_share * self.distant.world_pdf(n, d)

    def kind_names(self) -> list[str]:
        return [kind.kind for _, kind, _ in self.kinds]


def scene_radius(scene) -> float:
    """Radius of a sphere about the origin that holds every primitive of the scene."""
    extent = [0.0]
    extent += [float(np.abs(np.asarray(m.vertices)).max()) for m in scene.meshes if len(m.vertices)]
    extent += [float(np.abs(np.asarray(s.center)).max() + s.radius) for s in scene.spheres]
    extent += [float(np.abs(np.asarray(q.corners)).max()) for q in scene.quads]
    return float(np.sqrt(3.0) * max(extent))
