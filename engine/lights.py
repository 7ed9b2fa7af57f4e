"""Area lights: every emissive triangle, quad and sphere, sampled by area (eq. 2.11).

One light is picked with probability proportional to its power (area x mean
radiance), then a point uniform over its area (pdf 1/A).  A quad that is a
parallelogram (every rectangle: Blender Area lights, the Cornell ceiling light) is
one light sampled as v00 + u1 e1 + u2 e2; other quads are split into two triangles.
Emissive surfaces are two-sided, as Cycles mesh lights; light-only AreaLights
(Blender Area lights) are one-sided unless marked two-sided.  Samples are rows
(engine/vec.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sampling import uniform_sphere, uniform_triangle
from .vec import max_abs3, rows

# Shadow-ray end points are pulled off the light by this relative amount (as the
# triangle spawn offset) so the ray never reports the light itself as occluder.
LIGHT_OFFSET = 2.0 ** -20
PARALLELOGRAM_TOLERANCE = 1e-9       # |v00 + v11 - v10 - v01| relative to the quad's size


@dataclass
class LightSample:
    point: np.ndarray      # (3, N) on the light
    normal: np.ndarray     # (3, N) unit normal of the light at the point
    radiance: np.ndarray   # (3, N) emitted radiance Le
    inv_pdf: np.ndarray    # (N,) area / selection probability: 1 / p(y) in eq. 2.11
    offset: np.ndarray     # (N,) distance along the normal that clears the light
    one_sided: np.ndarray  # (N,) bool: emits only towards the side its normal faces


def is_parallelogram(c: np.ndarray) -> bool:
    size = np.abs(c - c[0]).max()
    return bool(np.abs(c[0] + c[2] - c[1] - c[3]).max() <= PARALLELOGRAM_TOLERANCE * max(size, 1e-300))


class LightSampler:
    def __init__(self, scene):
        mats = scene.materials
        emission = np.array([m.emission for m in mats], dtype=np.float64).reshape(-1, 3)
        emissive = emission.max(axis=1) > 0
        # Flat patches (triangles and parallelograms) as v0 + b1 e1 + b2 e2, gathered as
        # arrays of (corner a, corner b, corner c, radiance, is parallelogram, one-sided).
        parts = []

        def add(a, b, c, radiance, parallelogram, single_sided):
            a, b, c = (np.asarray(x, dtype=np.float64).reshape(-1, 3) for x in (a, b, c))
            n = len(a)
            parts.append((a, b, c, np.broadcast_to(radiance, (n, 3)), np.full(n, parallelogram),
                          np.full(n, single_sided)))

        for mesh in scene.meshes:
            ids = np.asarray(mesh.material_ids, dtype=np.int64)
            sel = emissive[ids] if len(ids) else np.zeros(0, bool)
            if sel.any():
                v = np.asarray(mesh.vertices, dtype=np.float64)[np.asarray(mesh.triangles)[sel]]   # (k, 3, 3)
                add(v[:, 0], v[:, 1], v[:, 2], emission[ids[sel]], False, False)
        for quad in scene.quads:
            if emissive[quad.material_id]:
                self._add_quad(np.asarray(quad.corners, dtype=np.float64), emission[quad.material_id], False, add)
        for light in scene.lights:
            radiance = np.asarray(light.radiance, dtype=np.float64)
            corners = np.asarray(light.vertices, dtype=np.float64)
            if len(corners) == 4:
                self._add_quad(corners, radiance, not light.two_sided, add)
            else:                               # a polygon (Blender disk/ellipse): a fan
                t = light.triangles()
                add(t[:, 0], t[:, 1], t[:, 2], radiance, False, not light.two_sided)
        a, b, c, le, para, one_sided = (
            [np.concatenate(column) for column in zip(*parts)] if parts
            else [np.zeros((0, 3))] * 4 + [np.zeros(0, bool)] * 2)
        self.v0, self.e1, self.e2 = rows(a), rows(b - a), rows(c - a)
        self.le = rows(le)
        self.parallelogram, self.patch_one_sided = para, one_sided
        cross = np.cross(b - a, c - a).reshape(-1, 3)
        doubled = np.linalg.norm(cross, axis=1)
        self.patch_area = np.where(self.parallelogram, doubled, 0.5 * doubled)
        self.patch_normal = rows(cross / np.maximum(doubled, 1e-300)[:, None])
        self.n_patch = len(self.patch_area)

        # Zero-area emitters carry no power and are never picked (hard case S8).
        spheres = [s for s in scene.spheres if emissive[s.material_id]]
        self.sph_center = rows([s.center for s in spheres])
        self.sph_radius = np.array([s.radius for s in spheres], dtype=np.float64)
        self.sph_le = rows(emission[[s.material_id for s in spheres]])
        self.sph_area = 4.0 * np.pi * self.sph_radius ** 2
        self.any_one_sided = bool(self.patch_one_sided.any())

        area = np.concatenate([self.patch_area, self.sph_area])
        mean_le = np.concatenate([self.le.mean(axis=0), self.sph_le.mean(axis=0)])
        power = area * mean_le
        self.count = int((power > 0).sum())
        self.total_power = float(power.sum())
        self.area = area
        self.prob = power / self.total_power if self.total_power > 0 else power
        self.cdf = np.cumsum(self.prob)

    @staticmethod
    def _add_quad(c, radiance, single_sided, add):
        if is_parallelogram(c):
            add(c[0], c[1], c[3], radiance, True, single_sided)
        else:
            add(c[0], c[1], c[2], radiance, False, single_sided)
            add(c[0], c[2], c[3], radiance, False, single_sided)

    def sample(self, u_pick: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> LightSample:
        n = len(u_pick)
        if len(self.cdf) == 1:                  # one light: no pick, no gathers
            index = np.zeros(n, dtype=np.int64)
            if self.n_patch == 1:
                b1, b2 = (u1, u2) if self.parallelogram[0] else uniform_triangle(u1, u2)
                point = self.v0 + b1 * self.e1 + b2 * self.e2
                normal = np.repeat(self.patch_normal, n, axis=1)
                radiance = np.repeat(self.le, n, axis=1)
                one_sided = np.full(n, self.patch_one_sided[0])
                inv_pdf = np.full(n, self.area[0] / self.prob[0])
                return LightSample(point, normal, radiance, inv_pdf, LIGHT_OFFSET * max_abs3(point), one_sided)
        else:
            index = np.minimum(np.searchsorted(self.cdf, u_pick * self.cdf[-1], side="right"), len(self.cdf) - 1)
        is_patch = index < self.n_patch
        if is_patch.all():                       # the common case: no spherical lights
            point, normal, radiance, one_sided = self._sample_patches(index, u1, u2)
        else:
            point, normal, radiance = np.empty((3, n)), np.empty((3, n)), np.empty((3, n))
            one_sided = np.zeros(n, dtype=bool)
            sel = np.flatnonzero(is_patch)
            if len(sel):
                p, nrm, le, side = self._sample_patches(index.take(sel), u1.take(sel), u2.take(sel))
                point[:, sel], normal[:, sel], radiance[:, sel], one_sided[sel] = p, nrm, le, side
            sel = np.flatnonzero(~is_patch)
            k = index.take(sel) - self.n_patch
            direction = uniform_sphere(u1.take(sel), u2.take(sel))
            point[:, sel] = self.sph_center.take(k, axis=1) + self.sph_radius.take(k) * direction
            normal[:, sel] = direction
            radiance[:, sel] = self.sph_le.take(k, axis=1)
        inv_pdf = self.area.take(index) / self.prob.take(index)
        return LightSample(point, normal, radiance, inv_pdf, LIGHT_OFFSET * max_abs3(point), one_sided)

    def _sample_patches(self, index, u1, u2):
        b1, b2 = uniform_triangle(u1, u2)
        if self.parallelogram.any():
            para = self.parallelogram.take(index)
            b1, b2 = np.where(para, u1, b1), np.where(para, u2, b2)
        point = self.v0.take(index, axis=1) + b1 * self.e1.take(index, axis=1) + b2 * self.e2.take(index, axis=1)
        return (point, self.patch_normal.take(index, axis=1), self.le.take(index, axis=1),
                self.patch_one_sided.take(index))
