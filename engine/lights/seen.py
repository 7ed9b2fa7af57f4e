"""Point, spot and sun lights seen in mirrors and through glass, as Cycles shows them.

Cycles' lights are invisible to camera rays but, by default, visible to glossy and transmission
rays (measured in Blender 5.0: a point light of radius r appears in a mirror as a disk of radiance
I / (pi r^2); a sun of angle theta as a disk of angular radius theta / 2 and radiance
E / (pi sin^2(theta / 2)), which makes its irradiance E).  The tracer lights diffuse surfaces with
these lamps by shadow rays only (engine/lights/points.py, distant.py), so a ray can reach them
only after a specular (mirror or glass) bounce, where no shadow ray could have found them: that
emission counts with weight 1 and nothing is counted twice.

A point light is met as the sphere of its radius (Cycles 4.0 and later; 3.x shows a disk facing the
viewer, the same outline to within (r / d)^2); a spot light's falloff is that of the direction from
the light to the ray's origin.  Lights without a radius and suns without an angle are points and
directions: no ray meets them.  Rays pass through lights (they cast no shadow in this tracer).
"""
from __future__ import annotations

import numpy as np

from ..geometry.shapes.spheres import intersect_sphere
from ..core.vec import dot
from .distant import SunLights
from .points import PointLights


class SeenLamps:
    """Emission of the round lamps and suns that rays reach, for glossy and transmission rays
    (each lamp for the kinds its visibility flags allow)."""

    def __init__(self, scene):
        def shown(light):
            return light.visible_glossy or light.visible_transmission
        bulbs = [i for i, p in enumerate(scene.points) if p.radius > 0 and max(p.intensity) > 0 and shown(p)]
        suns = [s for s in scene.suns if s.angle > 2e-6 and max(s.irradiance) > 0 and shown(s)]   # not delta
        self.points = PointLights(scene.points) if bulbs else None
        self.bulbs = np.array(bulbs, dtype=np.int64)
        self.suns = SunLights(suns, 1.0) if suns else None
        lights = [scene.points[i] for i in bulbs] + suns
        self.visible = {"glossy": np.array([light.visible_glossy for light in lights], dtype=bool),
                        "transmission": np.array([light.visible_transmission for light in lights], dtype=bool)}
        self.names = [light.name for light in lights]

    @classmethod
    def of(cls, scene):
        """SeenLamps for `scene`, or None when it has no lamp a ray can meet."""
        seen = cls(scene)
        return seen if seen.names else None

    def radiance(self, o, d, tmax, transmission) -> np.ndarray:
        """(3, N) emission along the rays (rows o, unit rows d) before distance tmax (inf: the
        ray escapes, and suns in its direction count too); `transmission` (N,) bool: the ray
        left through glass (else it was reflected)."""
        total = np.zeros(o.shape)
        visible = np.where(transmission[None, :], self.visible["transmission"][:, None],
                           self.visible["glossy"][:, None])               # (lights, N)
        for slot, j in enumerate(self.bulbs):
            c, r = self.points.center[:, j], float(self.points.radius[j])
            away = o - c[:, None]                                        # from the light to the origins
            outside = dot(away, away) > r * r
            t = intersect_sphere(o, d, c, r, tmax)
            hit = np.flatnonzero(visible[slot] & outside & (t < tmax))
            if len(hit):
                emitted = away.take(hit, axis=1)
                emitted = emitted / np.sqrt(dot(emitted, emitted))
                # The falloff of the direction from the light to the ray's origin, as Cycles has it.
                total[:, hit] += self.points.le(np.full(len(hit), j), None, -emitted)
        if self.suns is not None:
            escaped = np.isinf(tmax)
            for k in range(self.suns.count):
                rays = np.flatnonzero(visible[len(self.bulbs) + k] & escaped)
                if len(rays):                                           # 0 outside the sun's disk
                    total[:, rays] += self.suns.le(np.full(len(rays), k), None, d.take(rays, axis=1))
        return total
