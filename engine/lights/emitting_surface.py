"""What the emitting surfaces share (parallelograms, triangles, polygons, spheres; pbrt-v4's
DiffuseAreaLight over its shapes): a constant radiance per light, emitted from both sides (the
emissive surfaces of a scene, as Cycles' mesh lights) or from the front only (Blender Area lights
unless two-sided), the flux that follows from it, and rays leaving the surface.

A subclass sets `count`, `area` (K,), `radiance` and `one_sided` (with `_set_emission`) and
writes the parts that depend on its shape: sample_li, pdf_li and bounds (engine/lights/protocol.py),
`sample_area(idx, u1, u2)` (points uniform over the area and their normals) and
`normal_at(idx, point)`.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import dot, rows
from ..sampling.warps import ONE_MINUS_EPSILON, cosine_directions
from .protocol import EmissionSample, finite_sample


class EmittingSurface:
    at_infinity = False
    first = 0

    def _set_emission(self, radiance, one_sided) -> None:
        """radiance: (3,) or (K, 3), default 1; one_sided: bool or (K,), default two-sided."""
        radiance = (1.0, 1.0, 1.0) if radiance is None else radiance
        one_sided = False if one_sided is None else one_sided
        self.radiance = rows(np.broadcast_to(np.asarray(radiance, dtype=np.float64).reshape(-1, 3), (self.count, 3)))
        self.one_sided = np.broadcast_to(np.asarray(one_sided, dtype=bool).reshape(-1), (self.count,)).copy()

    def _li(self, x, idx, point, normal, pdf):
        """The LiSample of `point` on light idx, drawn with density `pdf`."""
        return finite_sample(x, point, normal, self.radiance.take(idx, axis=1), pdf)

    def le(self, idx, point, direction):
        facing = ~self.one_sided.take(idx) | (dot(self.normal_at(idx, point), direction) < 0.0)
        return np.where(facing, self.radiance.take(idx, axis=1), 0.0)

    def power(self):
        """pi x area x mean radiance per side (Lambertian emission)."""
        sides = np.where(self.one_sided, 1.0, 2.0)
        return np.pi * self.area * self.radiance.mean(axis=0) * sides

    def report_power(self):
        return self.area * self.radiance.mean(axis=0)

    def sample_emission(self, idx, u1, u2, u3, u4, targets=None):
        """Origin uniform over the area (u1, u2; pdf_pos 1 / A), direction cosine-distributed about
        the side it leaves from (u3, u4); a two-sided light leaves from either side with
        probability 1/2 (u3 < 1/2: the back, u3 rescaled to [0, 1) for the direction).  With
        `targets` (engine/lights/aim.py SphereTargets) the direction is aimed at them instead
        (pdf_dir their mixture density) and leaves from the side it points to."""
        origin, normal = self.sample_area(idx, u1, u2)
        normal = np.array(np.broadcast_to(normal, origin.shape))
        two_sided = ~self.one_sided.take(idx)
        if targets is not None:
            direction, pdf_dir = targets.directions(origin, u3, u4)
            normal *= np.where(dot(direction, normal) < 0.0, -1.0, 1.0)
            return EmissionSample(origin, direction, normal, self.le(idx, origin, -direction),
                                  1.0 / self.area.take(idx), pdf_dir)
        back = two_sided & (u3 < 0.5)
        u3 = np.where(two_sided, np.minimum(np.where(back, 2.0 * u3, 2.0 * u3 - 1.0), ONE_MINUS_EPSILON), u3)
        normal[:, back] *= -1.0
        direction = cosine_directions(u3, u4, normal)
        pdf_dir = np.maximum(dot(direction, normal), 0.0) * (1.0 / np.pi) * np.where(two_sided, 0.5, 1.0)
        return EmissionSample(origin, direction, normal, self.radiance.take(idx, axis=1),
                              1.0 / self.area.take(idx), pdf_dir)
