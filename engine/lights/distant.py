"""Lights at infinity: Blender sun lights and the world (a constant background radiance).

Sun j: directions uniform in the cone of half-angle alpha_j = angle_j / 2 about -direction_j,
p_w = 1 / (2 pi (1 - cos alpha)), radiance E / (pi sin^2 alpha) so that a surface facing the
sun receives the irradiance E; a sun of angle 0 is a delta light (one direction, E cos theta).
The world: directions cosine-distributed about the receiver's normal, p_w = cos theta / pi, so
a diffuse receiver under an unoccluded sky gets a zero-variance estimate.

All of them are picked by flux (a sun's E through the scene's cross-section, the world's through
a sphere around the scene).  Shadow rays to them run to t = inf; a bounce ray that escapes
reaches the world (the integrator's misses stage weighs that by MIS); suns are reached by
shadow rays only.
"""
from __future__ import annotations

import numpy as np

from ..sampling.warps import cosine_directions, uniform_cone
from ..core.vec import dot, rows


class DistantLights:
    kind = "distant"

    def __init__(self, suns, background, scene_radius: float):
        r2 = max(scene_radius, 1e-300) ** 2
        irradiance = np.array([s.irradiance for s in suns], dtype=np.float64).reshape(-1, 3)
        d = np.array([s.direction for s in suns], dtype=np.float64).reshape(-1, 3)
        self.axis = rows(-d / np.linalg.norm(d, axis=1)[:, None])          # towards each sun
        half = np.array([0.5 * s.angle for s in suns], dtype=np.float64)
        self.one_minus_cos = 2.0 * np.sin(0.5 * half) ** 2             # 1 - cos(half), no cancellation
        self.delta = half < 1e-6
        sin2 = np.where(self.delta, 1.0, np.sin(half) ** 2)
        radiance = [np.where(self.delta[:, None], irradiance, irradiance / (np.pi * sin2)[:, None])]
        power = [np.pi * r2 * irradiance.mean(axis=1)]
        self.world_slot = None
        if max(background) > 0:
            self.world_slot = len(suns)
            radiance.append(np.asarray(background, dtype=np.float64)[None, :])
            power.append(np.array([np.pi * float(np.mean(background)) * 4.0 * np.pi * r2]))
        self.radiance = rows(np.concatenate(radiance))
        self.power = np.concatenate(power)
        self.count = len(self.power)
        total = self.power.sum()
        self.prob = self.power / total if total > 0 else np.full(self.count, 1.0 / max(self.count, 1))
        self.cdf = np.cumsum(self.prob)

    def sample(self, n, u_pick, u1, u2):
        """(unit directions, P(j) p_w, slot j) for receivers with facing normals n (rows); a delta
        sun's 'density' is 1 (its radiance is the irradiance E)."""
        m = len(u_pick)
        slot = np.minimum(np.searchsorted(self.cdf, u_pick * self.cdf[-1], side="right"), self.count - 1)
        direction, pdf = np.empty((3, m)), np.empty(m)
        world = np.zeros(m, dtype=bool) if self.world_slot is None else slot == self.world_slot
        if world.any():
            w = np.flatnonzero(world)
            direction[:, w] = cosine_directions(u1.take(w), u2.take(w), n.take(w, axis=1))
            pdf[w] = np.maximum(dot(direction[:, w], n.take(w, axis=1)), 0.0) * (1.0 / np.pi)
        sun = np.flatnonzero(~world)
        if len(sun):
            j = slot.take(sun)
            one_minus = self.one_minus_cos.take(j)
            direction[:, sun], _ = uniform_cone(u1.take(sun), u2.take(sun), self.axis.take(j, axis=1), one_minus)
            pdf[sun] = np.where(self.delta.take(j), 1.0, 1.0 / (2.0 * np.pi * np.maximum(one_minus, 1e-300)))
        return direction, pdf * self.prob.take(slot), slot

    def world_pdf(self, n, d):
        """P(world) p_w of direction d at receivers with facing normals n."""
        return self.prob[self.world_slot] * np.maximum(dot(d, n), 0.0) * (1.0 / np.pi)
