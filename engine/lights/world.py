"""The world (a constant background radiance) as a light: directions cosine-distributed about
the receiver's normal, p_w = cos(theta) / pi, so a diffuse receiver under an unoccluded sky
gets a zero-variance estimate.  The light is at infinity: shadow rays run to t = inf, and a
bounce ray that escapes reaches it (the integrator's misses stage weighs that by MIS)."""
from __future__ import annotations

import numpy as np

from ..sampling import cosine_directions
from ..vec import dot


class WorldLight:
    kind = "world"

    def __init__(self, radiance, scene_radius: float):
        self.radiance = np.asarray(radiance, dtype=np.float64)
        # Flux through a sphere around the scene: what the selection weighs it by.
        self.power = float(np.pi * self.radiance.mean() * 4.0 * np.pi * max(scene_radius, 1e-300) ** 2)

    @staticmethod
    def sample(n, u1, u2):
        """(unit directions, p_w) about the facing normals n (rows)."""
        d = cosine_directions(u1, u2, n)
        return d, np.maximum(dot(d, n), 0.0) * (1.0 / np.pi)

    @staticmethod
    def pdf(n, d):
        return np.maximum(dot(d, n), 0.0) * (1.0 / np.pi)
