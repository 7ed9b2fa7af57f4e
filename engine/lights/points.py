"""Blender point lights as Cycles has them (measured in 3.4 and 5.0): intensity I [W/sr] from a
position; with a radius r, a disk of radius r facing the receiver, of radiance I / (pi r^2).

With r > 0 directions are drawn uniformly in the cone the disk subtends (half-angle
atan(r / d)), p_w = 1 / (2 pi (1 - cos beta)), the point where the direction meets the disk's
plane; with r = 0 the light is a delta light: the point itself, and a 'density' d^2 so that
radiance / density = I / d^2.  Point lights are reached by shadow rays only (not by bounce
rays), so their shadow rays always have MIS weight 1.

Spot lights are point lights whose radiance is scaled by the cone's falloff a(theta) in the
direction of the receiver (engine/scene/model.py PointLight; Cycles evaluates it for the direction from
the sampled point to the receiver, as `spot_factor` does).  Their samples are drawn as the point
light's: the falloff only scales what a sample carries.
"""
from __future__ import annotations

import numpy as np

from ..sampling.warps import uniform_cone
from ..core.vec import dot, gather, rows


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
        self.spots = np.flatnonzero([p.is_spot for p in points])
        if len(self.spots):
            spots = [points[i] for i in self.spots]
            axis = np.array([p.spot_direction for p in spots], dtype=np.float64)
            self.spot_axis = rows(axis / np.linalg.norm(axis, axis=1, keepdims=True))
            self.spot_cos_half = np.array([np.cos(0.5 * p.spot_size) for p in spots])
            self.spot_width = (1.0 - self.spot_cos_half) * np.array([p.spot_blend for p in spots])
            self.spot_cosine = np.array([p.spot_falloff == "cosine-smoothstep" for p in spots])
            self.spot_slot = np.full(self.count, -1, dtype=np.int64)
            self.spot_slot[self.spots] = np.arange(len(spots))

    def spot_factor(self, idx, emitted) -> np.ndarray:
        """The falloff a(theta) of light `idx` (local numbers) for unit rows `emitted`, the
        directions from the light to the receivers: 1 for point lights."""
        factor = np.ones(len(idx))
        if not len(self.spots):
            return factor
        slot = self.spot_slot.take(idx)
        sel = np.flatnonzero(slot >= 0)
        if len(sel):
            k = slot.take(sel)
            c = dot(gather(self.spot_axis, k), emitted.take(sel, axis=1))
            c0, width = self.spot_cos_half.take(k), self.spot_width.take(k)
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.clip(np.where(width > 0, (c - c0) / width, np.inf), 0.0, 1.0)
            a = np.where(c > c0, t * t * (3.0 - 2.0 * t), 0.0)          # smoothstep(0, 1, .)
            factor[sel] = np.where(self.spot_cosine.take(k), c * a, a)
        return factor

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
