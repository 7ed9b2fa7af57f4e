"""Blender point lights as Cycles has them (measured in 3.4 and 5.0): intensity I [W/sr] from a
position; with a radius r, a disk of radius r facing the receiver, of radiance I / (pi r^2).

With r > 0 directions are drawn uniformly in the cone the disk subtends (half-angle
atan(r / d)), p_w = 1 / (2 pi (1 - cos beta)), the point where the direction meets the disk's
plane; with r = 0 the light is a delta light: the point itself, and a 'density' d^2 so that
radiance / density = I / d^2.  Point lights are reached by shadow rays only (not by bounce
rays), so their shadow rays always have MIS weight 1.
"""
from __future__ import annotations

import numpy as np

from ..sampling import uniform_cone
from ..vec import dot, gather, rows


class PointLights:
    kind = "point"

    def __init__(self, points):
        self.center = rows([p.position for p in points])
        self.radius = np.array([p.radius for p in points], dtype=np.float64)
        self.count = len(points)
        self.area = np.pi * self.radius ** 2                       # of the disk: the power pmf's share
        intensity = np.array([p.intensity for p in points], dtype=np.float64).reshape(-1, 3)
        disk = self.radius > 0
        self.radiance_rows = rows(np.where(disk[:, None], intensity / np.maximum(self.area, 1e-300)[:, None],
                                           intensity))
        self.flux = 4.0 * np.pi * intensity.mean(axis=1)

    def sample(self, x, idx, u1, u2, solid_angle: bool = True):
        c, r = gather(self.center, idx), gather(self.radius, idx)
        axis = c - x
        d2 = dot(axis, axis)
        d = np.sqrt(d2)
        with np.errstate(divide="ignore", invalid="ignore"):
            axis = axis / d
            tan_b = r / d
        cos_b = 1.0 / np.sqrt(1.0 + tan_b * tan_b)
        one_minus = tan_b * tan_b * cos_b * cos_b / (1.0 + cos_b)         # 1 - cos beta, no cancellation
        w, cos_t = uniform_cone(u1, u2, axis, one_minus)
        with np.errstate(divide="ignore", invalid="ignore"):
            point = x + (d / cos_t) * w                                   # on the disk's plane
            pdf = np.where(r > 0, 1.0 / (2.0 * np.pi * one_minus), d2)
        point = np.where(r > 0, point, np.broadcast_to(c, x.shape))
        return point, np.broadcast_to(-axis, x.shape).copy(), np.where(np.isfinite(pdf), pdf, 0.0)
