"""Spherical emitters: the cone of directions from outside, uniform area from inside.

From outside (|x - c| > r) the directions to the sphere fill a cone of half-angle
theta_max, sin^2 theta_max = r^2 / |x - c|^2; they are drawn uniformly in it (pbrt-v4's
`Sphere::Sample(ctx)`), p_w = 1 / (2 pi (1 - cos theta_max)) with 1 - cos theta_max
written as sin^2 / (1 + cos) (no cancellation for far spheres).  The point on the sphere
comes from the angle at the centre, without a ray-sphere test that could miss at the
silhouette.  From inside or on the sphere: a point uniform over its area, p_A = 1/(4 pi r^2),
p_w = d^2 / (A |cos theta_y|) (zero variance inside a uniform emitting sphere: docs/hard-cases.md T1).
`sample_li` and `pdf_li` share the inside test.  As area sampling (the report's estimator),
`solid_angle=False` always takes the area branch.
"""
from __future__ import annotations

import numpy as np

from ..sampling.warps import orthonormal_basis, uniform_sphere, unit_circle
from ..core.vec import dot, rows
from .emitting_surface import EmittingSurface
from .parallelograms import area_pdf
from .protocol import LightBounds

OUTSIDE = 1.0 + 1e-6          # |x - c|^2 > r^2 * OUTSIDE: sampled by cone


class Spheres(EmittingSurface):
    name = "sphere"

    def __init__(self, centers, radii, radiance=None, one_sided=None):
        """centers (K, 3), radii (K,); radiance, one_sided (the outside only): as EmittingSurface."""
        self.center = rows(centers)
        self.radius = np.asarray(radii, dtype=np.float64).reshape(-1)
        self.count = len(self.radius)
        self.area = 4.0 * np.pi * self.radius ** 2
        self._set_emission(radiance, one_sided)

    def _cone(self, x, idx):
        rel = self.center.take(idx, axis=1) - x
        dc2 = dot(rel, rel)
        r = self.radius.take(idx)
        outside = dc2 > r * r * OUTSIDE
        with np.errstate(divide="ignore", invalid="ignore"):
            sin2_max = np.where(outside, r * r / dc2, 1.0)
        cos_max = np.sqrt(np.maximum(1.0 - sin2_max, 0.0))
        one_minus_cos = sin2_max / (1.0 + cos_max)
        return rel, dc2, outside, sin2_max, one_minus_cos

    def sample_li(self, x, idx, u1, u2, n=None, solid_angle: bool = True):
        c, r = self.center.take(idx, axis=1), self.radius.take(idx)
        point, normal = self.sample_area(idx, u1, u2)         # by area
        pdf = area_pdf(x, point, normal, self.area.take(idx))
        if solid_angle:
            rel, dc2, outside, sin2_max, m = self._cone(x, idx)
            if outside.any():
                sel = np.flatnonzero(outside)
                n_cone = self._cone_normal(rel.take(sel, axis=1), dc2.take(sel), sin2_max.take(sel),
                                           m.take(sel), u1.take(sel), u2.take(sel))
                normal[:, sel] = n_cone
                point[:, sel] = c.take(sel, axis=1) + r.take(sel) * n_cone
                pdf[sel] = 1.0 / (2.0 * np.pi * m.take(sel))
        return self._li(x, idx, point, normal, pdf)

    @staticmethod
    def _cone_normal(rel, dc2, sin2_max, m, u1, u2):
        """Normal at the sphere point seen in the direction at angle theta in the cone."""
        w = rel / np.sqrt(dc2)                                # towards the centre
        eps = u1 * m
        cos_t = 1.0 - eps
        sin2_t = eps * (2.0 - eps)
        sin_max = np.sqrt(sin2_max)
        cos_alpha = sin2_t / sin_max + cos_t * np.sqrt(np.maximum(1.0 - sin2_t / sin2_max, 0.0))
        sin_alpha = np.sqrt(np.maximum(1.0 - cos_alpha * cos_alpha, 0.0))
        t1, t2 = orthonormal_basis(w)
        cphi, sphi = unit_circle(u2)
        return -(cos_alpha * w + sin_alpha * (cphi * t1 + sphi * t2))

    def pdf_li(self, x, idx, point, n=None, direction=None, solid_angle: bool = True):
        normal = self.normal_at(idx, point)
        pdf = area_pdf(x, point, normal, self.area.take(idx))
        if solid_angle:
            _, _, outside, _, m = self._cone(x, idx)
            pdf = np.where(outside, 1.0 / (2.0 * np.pi * np.where(outside, m, 1.0)), pdf)
        return pdf

    def solid_angle(self, x, idx):
        _, _, outside, _, m = self._cone(x, idx)
        return np.where(outside, 2.0 * np.pi * m, 4.0 * np.pi)

    def bounds(self):
        return LightBounds(self.center, self.radius, rows(np.tile([0.0, 0.0, 1.0], (self.count, 1))),
                           np.full(self.count, -1.0))                  # normals in every direction

    def sample_area(self, idx, u1, u2):
        normal = uniform_sphere(u1, u2)
        return self.center.take(idx, axis=1) + self.radius.take(idx) * normal, normal

    def normal_at(self, idx, point):
        return (point - self.center.take(idx, axis=1)) / self.radius.take(idx)
