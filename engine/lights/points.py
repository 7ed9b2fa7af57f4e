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

Rays leaving a point light (sample_emission): directions uniform over the sphere (a spot light's:
uniform in its cone), from a point uniform on the disk of radius r that faces the direction (the
disk every receiver in that direction sees).  Aimed at target spheres (caustic photons,
engine/lights/aim.py), the directions are the targets' from the light's centre, each sphere grown by
the light's radius: a ray from any point of the disk that meets a sphere of radius R is within
R + r of its centre, so the grown cones hold every such ray; a spot's falloff then scales (or
zeroes) what each ray carries.  A spot light whose cone is narrower than the targets' (their solid
angles) keeps its cone instead.
"""
from __future__ import annotations

import numpy as np

from ..sampling.warps import orthonormal_basis, uniform_cone, uniform_sphere, unit_circle
from ..core.vec import dot, gather, rows
from .aim import SphereTargets
from .protocol import EmissionSample, LightBounds, finite_sample


class PointLights:
    name = "point"
    at_infinity = False
    first = 0

    def __init__(self, points):
        """points: engine/scene/model.py PointLight (spot lights included)."""
        self.center = rows([p.position for p in points])
        self.radius = np.array([p.radius for p in points], dtype=np.float64)
        self.count = len(points)
        self.area = np.pi * self.radius ** 2                       # of the disk
        intensity = np.array([p.intensity for p in points], dtype=np.float64).reshape(-1, 3)
        disk = self.radius > 0
        # The disk's radiance I / (pi r^2); without a radius the intensity I (the delta convention).
        self.radiance = rows(np.where(disk[:, None], intensity / np.maximum(self.area, 1e-300)[:, None], intensity))
        self.one_sided = np.zeros(self.count, dtype=bool)
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

    # -- the light protocol (engine/lights/protocol.py) ----------------------------------
    def _cone(self, x, idx):
        """(centre, radius, unit axis x -> centre, distance, its square, 1 - cos beta) of the cone
        of directions from x to the disk of radius r facing x."""
        c, r = gather(self.center, idx), gather(self.radius, idx)
        axis = c - x
        d2 = dot(axis, axis)
        d = np.sqrt(d2)
        with np.errstate(divide="ignore", invalid="ignore"):
            axis = axis / d
            tan_b = r / d
        cos_b = 1.0 / np.sqrt(1.0 + tan_b * tan_b)
        one_minus = tan_b * tan_b * cos_b * cos_b / (1.0 + cos_b)         # 1 - cos beta, no cancellation
        return c, r, axis, d, d2, one_minus

    @staticmethod
    def _cone_pdf(r, d2, one_minus):
        """1 / (2 pi (1 - cos beta)); a delta light (r = 0): d^2, so radiance / pdf = I / d^2."""
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf = np.where(r > 0, 1.0 / (2.0 * np.pi * one_minus), d2)
        return np.where(np.isfinite(pdf), pdf, 0.0)

    def sample_li(self, x, idx, u1, u2, n=None, solid_angle: bool = True):
        """A direction uniform in the cone of the disk, the point where it meets the disk's plane."""
        c, r, axis, d, d2, one_minus = self._cone(x, idx)
        w, cos_t = uniform_cone(u1, u2, axis, one_minus)
        with np.errstate(divide="ignore", invalid="ignore"):
            point = x + (d / cos_t) * w                                   # on the disk's plane
        pdf = self._cone_pdf(r, d2, one_minus)
        point = np.where(r > 0, point, np.broadcast_to(c, x.shape))
        s = finite_sample(x, point, np.broadcast_to(-axis, x.shape).copy(), self.radiance.take(idx, axis=1), pdf)
        if len(self.spots):                                   # the cone's falloff towards the receiver
            s.radiance *= self.spot_factor(idx, -s.direction)
        return s

    def pdf_li(self, x, idx, point, n=None, direction=None, solid_angle: bool = True):
        _, r, _, _, d2, one_minus = self._cone(x, idx)
        return self._cone_pdf(r, d2, one_minus)

    def le(self, idx, point, direction):
        """The disk's radiance (the intensity without a radius), times a spot's falloff for the
        direction -`direction` the light emits into."""
        radiance = self.radiance.take(idx, axis=1)
        if len(self.spots):
            radiance *= self.spot_factor(idx, -direction)
        return radiance

    def power(self):
        """4 pi I (a spot light too: the cone does not concentrate its power, engine/scene/model.py)."""
        return self.flux

    def report_power(self):
        return self.flux / np.pi

    def bounds(self):
        return LightBounds(self.center, self.radius, rows(np.tile([0.0, 0.0, 1.0], (self.count, 1))),
                           np.full(self.count, -1.0))                  # emits in every direction

    def sample_emission(self, idx, u1, u2, u3, u4, targets=None):
        """Direction uniform over the sphere (u1, u2; pdf_dir 1 / 4 pi), a spot light's uniform in
        its cone (pdf_dir 1 / (2 pi (1 - cos(size / 2)))); origin uniform on the disk of radius r
        facing it (u3, u4; pdf_pos 1 / (pi r^2); a point without a radius: the centre, pdf_pos 1,
        radiance its intensity), so radiance / (pdf_pos pdf_dir) = 4 pi I x falloff for a point
        light (the falloff's solid angle for a spot).  With `targets` (engine/lights/aim.py
        SphereTargets) the direction is aimed from the centre at the targets grown by the light's
        radius, pdf_dir their mixture density."""
        direction = uniform_sphere(u1, u2)
        pdf_dir = np.full(len(u1), 1.0 / (4.0 * np.pi))
        aim = np.zeros(len(idx), bool) if targets is None else self._aims(idx, targets)
        if len(self.spots):
            slot = self.spot_slot.take(idx)
            sel = np.flatnonzero((slot >= 0) & ~aim)
            if len(sel):
                k = slot.take(sel)
                one_minus = 1.0 - self.spot_cos_half.take(k)
                direction[:, sel], _ = uniform_cone(u1.take(sel), u2.take(sel), gather(self.spot_axis, k), one_minus)
                pdf_dir[sel] = 1.0 / (2.0 * np.pi * one_minus)
        if aim.any():
            sel = np.flatnonzero(aim)
            direction[:, sel], pdf_dir[sel] = self._aimed(idx.take(sel), u1.take(sel), u2.take(sel), targets)
        t1, t2 = orthonormal_basis(direction)
        cphi, sphi = unit_circle(u4)
        r = gather(self.radius, idx)
        s = r * np.sqrt(u3)
        origin = gather(self.center, idx) + s * (cphi * t1 + sphi * t2)
        pdf_pos = np.broadcast_to(np.where(r > 0, 1.0 / np.maximum(np.pi * r * r, 1e-300), 1.0), (len(u1),)).copy()
        return EmissionSample(origin, direction, direction, self.le(idx, origin, -direction), pdf_pos, pdf_dir)

    def _aims(self, idx, targets):
        """(N,) whether the rays of lights idx are aimed at the targets: a point light's always; a
        spot light's when the targets' cones (grown by its radius) span less solid angle than its
        own cone, else they fill its cone (either draws every ray that carries light into a target)."""
        aim = np.ones(len(idx), bool)
        if not len(self.spots):
            return aim
        for light in np.unique(idx.take(np.flatnonzero(self.spot_slot.take(idx) >= 0))):
            grown = SphereTargets(targets.center, targets.radius + self.radius[light])
            cone = 2.0 * np.pi * (1.0 - self.spot_cos_half[self.spot_slot[light]])
            aim[idx == light] = grown.solid_angle(self.center[:, light]) < cone
        return aim

    def _aimed(self, idx, u1, u2, targets):
        """(directions (3, N), their density per unit solid angle) aimed from the lights' centres at
        the target spheres grown by each light's radius."""
        direction, pdf = np.zeros((3, len(idx))), np.zeros(len(idx))
        radius = self.radius.take(idx)
        for r in np.unique(radius):
            sel = np.flatnonzero(radius == r)
            grown = SphereTargets(targets.center, targets.radius + r)
            direction[:, sel], pdf[sel] = grown.directions(gather(self.center, idx.take(sel)), u1.take(sel),
                                                           u2.take(sel))
        return direction, pdf
