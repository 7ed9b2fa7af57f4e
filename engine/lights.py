"""Area lights: every emissive triangle, quad and sphere, sampled by area (eq. 2.11).

One light is picked with probability proportional to its power (area x mean
radiance), then a point uniform over its area (pdf 1/A).  Quads are split into two
triangles for sampling.  Emissive surfaces are two-sided, as Cycles mesh lights;
light-only AreaLights (Blender Area lights) are one-sided unless marked two-sided.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sampling import uniform_sphere, uniform_triangle
from .vec import max_abs3

# Shadow-ray end points are pulled off the light by this relative amount (as the
# triangle spawn offset) so the ray never reports the light itself as occluder.
LIGHT_OFFSET = 2.0 ** -20


@dataclass
class LightSample:
    point: np.ndarray      # (N, 3) on the light
    normal: np.ndarray     # (N, 3) unit normal of the light at the point
    radiance: np.ndarray   # (N, 3) emitted radiance Le
    inv_pdf: np.ndarray    # (N,) area / selection probability: 1 / p(y) in eq. 2.11
    offset: np.ndarray     # (N,) distance along the normal that clears the light
    one_sided: np.ndarray  # (N,) bool: emits only towards the side its normal faces


class LightSampler:
    def __init__(self, scene):
        mats = scene.materials
        emission = np.array([m.emission for m in mats], dtype=np.float64).reshape(-1, 3)
        emissive = emission.max(axis=1) > 0
        tris, tri_le = [], []
        for mesh in scene.meshes:
            sel = emissive[mesh.material_ids] if len(mesh.material_ids) else np.zeros(0, bool)
            if sel.any():
                tris.append(mesh.vertices[mesh.triangles[sel]])
                tri_le.append(emission[mesh.material_ids[sel]])
        for quad in scene.quads:
            if emissive[quad.material_id]:
                c = np.asarray(quad.corners, dtype=np.float64)
                tris.append(np.stack([c[[0, 1, 2]], c[[0, 2, 3]]]))
                tri_le.append(np.repeat(emission[quad.material_id][None], 2, axis=0))
        one_sided = [np.zeros(sum(len(t) for t in tris), dtype=bool)]
        for light in scene.lights:
            t = light.triangles()
            tris.append(t)
            tri_le.append(np.repeat(np.asarray(light.radiance, dtype=np.float64)[None], len(t), axis=0))
            one_sided.append(np.full(len(t), not light.two_sided))
        self.tri_one_sided = np.concatenate(one_sided)
        self.tri = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
        self.tri_le = np.concatenate(tri_le) if tri_le else np.zeros((0, 3))
        cross = np.cross(self.tri[:, 1] - self.tri[:, 0], self.tri[:, 2] - self.tri[:, 0])
        self.tri_area = 0.5 * np.linalg.norm(cross, axis=1)
        self.tri_normal = cross / np.maximum(2.0 * self.tri_area, 1e-300)[:, None]
        self.tri_v0 = self.tri[:, 0]
        self.tri_e1 = self.tri[:, 1] - self.tri[:, 0]
        self.tri_e2 = self.tri[:, 2] - self.tri[:, 0]
        # Zero-area emitters carry no power and are never picked (hard case S8).
        spheres = [s for s in scene.spheres if emissive[s.material_id]]
        self.sph_center = np.array([s.center for s in spheres], dtype=np.float64).reshape(-1, 3)
        self.sph_radius = np.array([s.radius for s in spheres], dtype=np.float64)
        self.sph_le = emission[[s.material_id for s in spheres]].reshape(-1, 3)
        self.sph_area = 4.0 * np.pi * self.sph_radius ** 2
        self.any_one_sided = bool(self.tri_one_sided.any())

        area = np.concatenate([self.tri_area, self.sph_area])
        le = np.concatenate([self.tri_le, self.sph_le])
        power = area * le.mean(axis=1) if len(area) else np.zeros(0)
        self.count = int((power > 0).sum())
        self.total_power = float(power.sum())
        self.area = area
        self.prob = power / self.total_power if self.total_power > 0 else power
        self.cdf = np.cumsum(self.prob)
        self.n_tri = len(self.tri_area)

    def sample(self, u_pick: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> LightSample:
        n = len(u_pick)
        index = np.searchsorted(self.cdf, u_pick * self.cdf[-1], side="right")
        index = np.minimum(index, len(self.cdf) - 1)
        is_tri = index < self.n_tri
        if is_tri.all():                       # the common case: no spherical lights
            b1, b2 = uniform_triangle(u1, u2)
            point = (self.tri_v0.take(index, axis=0) + b1[:, None] * self.tri_e1.take(index, axis=0)
                     + b2[:, None] * self.tri_e2.take(index, axis=0))
            normal = self.tri_normal.take(index, axis=0)
            radiance = self.tri_le.take(index, axis=0)
            one_sided = self.tri_one_sided.take(index)
        else:
            point = np.empty((n, 3))
            normal = np.empty((n, 3))
            radiance = np.empty((n, 3))
            one_sided = np.zeros(n, dtype=bool)
            if is_tri.any():
                k = index[is_tri]
                b1, b2 = uniform_triangle(u1[is_tri], u2[is_tri])
                point[is_tri] = self.tri_v0[k] + b1[:, None] * self.tri_e1[k] + b2[:, None] * self.tri_e2[k]
                normal[is_tri] = self.tri_normal[k]
                radiance[is_tri] = self.tri_le[k]
                one_sided[is_tri] = self.tri_one_sided[k]
            is_sph = ~is_tri
            k = index[is_sph] - self.n_tri
            direction = uniform_sphere(u1[is_sph], u2[is_sph])
            point[is_sph] = self.sph_center[k] + self.sph_radius[k, None] * direction
            normal[is_sph] = direction
            radiance[is_sph] = self.sph_le[k]
        inv_pdf = self.area.take(index) / self.prob.take(index)
        offset = LIGHT_OFFSET * max_abs3(point)
        return LightSample(point, normal, radiance, inv_pdf, offset, one_sided)
