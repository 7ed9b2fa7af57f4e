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
        left through glass (else it was reflected).

        No loop over lamps: the (ray, lamp) pairs that meet are found at once (the bulbs through
        their BoxTree, the suns as every escaped ray with every sun), and each ray's emission is
        summed over its pairs in lamp order (bulbs, then suns), the order a loop over the lamps
        adds them in, so the sums are the same bit for bit (tests/lights/test_seen.py)."""
        parts = []                                  # (ray, slot, le (3, P)) of the pairs that meet
        if self.bulb_tree is not None:
            parts.append(self._bulb_pairs(o, d, tmax, transmission))
        if self.suns is not None:
            parts.append(self._sun_pairs(d, tmax, transmission))
        parts = [part for part in parts if len(part[0])]
        total = np.zeros(o.shape)
        if not parts:
            return total
        ray, slot, le = (np.concatenate(a, axis=-1) for a in zip(*parts))
        if len(parts) > 1:                                              # bulbs and suns
            order = np.lexsort((slot, ray))                             # per ray in lamp order
            ray, le = ray.take(order), le.take(order, axis=1)
        for channel in range(3):
            total[channel] = np.bincount(ray, weights=le[channel], minlength=total.shape[1])
        return total

    def _visible(self, transmission, ray, slot):
        return np.where(transmission.take(ray), self.visible["transmission"].take(slot),
                        self.visible["glossy"].take(slot))

    def _bulb_pairs(self, o, d, tmax, transmission):
        """(ray, slot, le) of every bulb each ray meets before tmax, per ray in bulb order."""
        ray, slot = self.bulb_tree.all_pairs(o, d, tmax)                 # the bulbs each ray may meet
        visible = self._visible(transmission, ray, slot)
        ray, slot = ray[visible], slot[visible]
        j = self.bulbs.take(slot)
        c, r = self.points.center.take(j, axis=1), self.points.radius.take(j)
        start = o.take(ray, axis=1)
        away = start - c                                                 # from the light to the origins
        bound = tmax.take(ray)
        outside = dot(away, away) > r * r
        t = intersect_sphere(start, d.take(ray, axis=1), c, r, bound)
        hit = np.flatnonzero(outside & (t < bound))
        hit = hit[np.lexsort((slot.take(hit), ray.take(hit)))]          # per ray in bulb order
        emitted = away.take(hit, axis=1)
        emitted = emitted / np.sqrt(dot(emitted, emitted))
        # The falloff of the direction from the light to the ray's origin, as Cycles has it.
        return ray.take(hit), slot.take(hit), self.points.le(j.take(hit), None, -emitted)

    def _sun_pairs(self, d, tmax, transmission):
        """(ray, slot, le) of every escaped ray with every sun whose disk it points into."""
        escaped = np.flatnonzero(np.isinf(tmax))
        k = self.suns.count
        ray, sun = np.repeat(escaped, k), np.tile(np.arange(k), len(escaped))
        slot = sun + len(self.bulbs)
        visible = np.flatnonzero(self._visible(transmission, ray, slot))
        ray, sun, slot = ray.take(visible), sun.take(visible), slot.take(visible)
        # A sun adds 0 outside its disk, and x + 0 = x for the sums (no -0 among them): left out.
        inside = np.flatnonzero(~self.suns.delta.take(sun)
                                & (dot(d.take(ray, axis=1), self.suns.axis.take(sun, axis=1))
                                   >= self.suns.cos_half.take(sun)))
        return ray.take(inside), slot.take(inside), self.suns.le(sun.take(inside), None,
                                                                  d.take(ray.take(inside), axis=1))
