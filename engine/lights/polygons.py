"""Planar convex polygon emitters (Blender disk and ellipse Area lights, quads that are not
parallelograms), sampled uniformly by area: a fan triangle is picked in proportion to its
area, then a point uniform in it, so the density is 1/A over the whole polygon and
p_w = d^2 / (A |cos theta_y|), whatever `solid_angle` asks.  Unbiased and stable everywhere;
solid-angle sampling is not worth it for these rare shapes.
"""
from __future__ import annotations

import numpy as np

from ..sampling.warps import ONE_MINUS_EPSILON, uniform_triangle
from ..core.vec import rows
from .emitting_surface import EmittingSurface
from .parallelograms import area_pdf
from .protocol import LightBounds


class Polygons(EmittingSurface):
    name = "polygon"

    def __init__(self, polygons, radiance=None, one_sided=None):
        """polygons: list of (N_i, 3) corner arrays in order around each polygon (the normal follows
        that order counter-clockwise); radiance, one_sided: as EmittingSurface."""
        tri_a, tri_b, tri_c, owner = [], [], [], []
        for k, corners in enumerate(polygons):
            v = np.asarray(corners, dtype=np.float64).reshape(-1, 3)
            tri_a.append(np.repeat(v[:1], len(v) - 2, axis=0))
            tri_b.append(v[1:-1])
            tri_c.append(v[2:])
            owner.append(np.full(len(v) - 2, k))
        self.count = len(polygons)
        self._set_emission(radiance, one_sided)
        a = np.concatenate(tri_a) if tri_a else np.zeros((0, 3))
        b = np.concatenate(tri_b) if tri_b else np.zeros((0, 3))
        c = np.concatenate(tri_c) if tri_c else np.zeros((0, 3))
        owner = np.concatenate(owner) if owner else np.zeros(0, np.int64)
        cross = np.cross(b - a, c - a)
        tri_area = 0.5 * np.linalg.norm(cross, axis=1)
        self.area = np.bincount(owner, weights=tri_area, minlength=self.count)
        normal = np.zeros((self.count, 3))
        for axis in range(3):
            normal[:, axis] = np.bincount(owner, weights=cross[:, axis], minlength=self.count)
        self.normal = rows(normal / np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None])
        self.fan_first = np.searchsorted(owner, np.arange(self.count))           # first fan triangle
        self.fan_last = np.searchsorted(owner, np.arange(self.count), side="right") - 1
        self.cum = np.concatenate([[0.0], np.cumsum(tri_area)])              # over all fan triangles
        self.a, self.e1, self.e2, self.tri_area = rows(a), rows(b - a), rows(c - a), tri_area
        centroid = np.array([np.asarray(p, dtype=np.float64).reshape(-1, 3).mean(axis=0) for p in polygons]
                            ).reshape(-1, 3)
        self.center = rows(centroid)
        self.radius = np.array([np.linalg.norm(np.asarray(p, dtype=np.float64).reshape(-1, 3) - centroid[k],
                                               axis=1).max() for k, p in enumerate(polygons)])

    def sample_li(self, x, idx, u1, u2, n=None, solid_angle: bool = True):
        """By area whatever `solid_angle` asks."""
        point, normal = self.sample_area(idx, u1, u2)
        return self._li(x, idx, point, normal, area_pdf(x, point, normal, self.area.take(idx)))

    def sample_area(self, idx, u1, u2):
        """A fan triangle in proportion to its area (u1), then a point uniform in it (u1 rescaled, u2)."""
        start = self.cum.take(self.fan_first.take(idx))
        target = start + u1 * self.area.take(idx)
        tri = np.searchsorted(self.cum, target, side="right") - 1
        tri = np.clip(tri, self.fan_first.take(idx), self.fan_last.take(idx))     # rounding at the far end
        # u1 re-used inside the chosen triangle (its share of the interval, rescaled).
        with np.errstate(divide="ignore", invalid="ignore"):
            v1 = np.clip((target - self.cum.take(tri)) / self.tri_area.take(tri), 0.0, ONE_MINUS_EPSILON)
        b1, b2 = uniform_triangle(np.nan_to_num(v1), u2)
        point = self.a.take(tri, axis=1) + b1 * self.e1.take(tri, axis=1) + b2 * self.e2.take(tri, axis=1)
        return point, self.normal.take(idx, axis=1)

    def pdf_li(self, x, idx, point, n=None, direction=None, solid_angle: bool = True):
        return area_pdf(x, point, self.normal.take(idx, axis=1), self.area.take(idx))

    def solid_angle(self, x, idx):
        raise NotImplementedError("polygon lights are area-sampled")

    def bounds(self):
        return LightBounds(self.center, self.radius, self.normal, np.where(self.one_sided, 1.0, -1.0))

    def normal_at(self, idx, point):
        return self.normal.take(idx, axis=1)
