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

from ..geometry.shapes.box_tree import BoxTree, padded_boxes
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
        if bulbs:                                   # the bulbs' spheres, for the rays to find them
            center, radius = self.points.center.take(self.bulbs, axis=1).T, self.points.radius.take(self.bulbs)
            self.bulb_tree = BoxTree(*padded_boxes(center - radius[:, None], center + radius[:, None]))
        else:
            self.bulb_tree = None

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
        if self.bulb_tree is not None:
            self._add_bulbs(total, o, d, tmax, transmission)
        if self.suns is not None:
            escaped = np.isinf(tmax)
            for k in range(self.suns.count):
                slot = len(self.bulbs) + k
                visible = np.where(transmission, self.visible["transmission"][slot], self.visible["glossy"][slot])
                rays = np.flatnonzero(visible & escaped)
                if len(rays):                                           # 0 outside the sun's disk
                    total[:, rays] += self.suns.le(np.full(len(rays), k), None, d.take(rays, axis=1))
        return total

    def _add_bulbs(self, total, o, d, tmax, transmission):
        """Add the emission of every bulb each ray meets before tmax, summed in bulb order."""
        ray, slot = self.bulb_tree.all_pairs(o, d, tmax)                 # the bulbs each ray may meet
        visible = np.where(transmission.take(ray), self.visible["transmission"].take(slot),
                           self.visible["glossy"].take(slot))
        ray, slot = ray[visible], slot[visible]
        j = self.bulbs.take(slot)
        c, r = self.points.center.take(j, axis=1), self.points.radius.take(j)
        start = o.take(ray, axis=1)
        away = start - c                                                 # from the light to the origins
        bound = tmax.take(ray)
        outside = dot(away, away) > r * r
        t = intersect_sphere(start, d.take(ray, axis=1), c, r, bound)
        hit = np.flatnonzero(outside & (t < bound))
        if not len(hit):
            return
        hit = hit[np.lexsort((slot.take(hit), ray.take(hit)))]          # per ray in bulb order, as a loop adds
        emitted = away.take(hit, axis=1)
        emitted = emitted / np.sqrt(dot(emitted, emitted))
        # The falloff of the direction from the light to the ray's origin, as Cycles has it.
        le = self.points.le(j.take(hit), None, -emitted)
        rays = ray.take(hit)
        for channel in range(3):
            total[channel] += np.bincount(rays, weights=le[channel], minlength=total.shape[1])
