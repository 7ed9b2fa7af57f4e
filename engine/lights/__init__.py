"""Lights: every emitter of a scene, how a shading point picks one, and how it samples it.

* protocol.py: what every kind of light offers (sample_li, pdf_li, le, power, bounds, sample_emission);
  emitting_surface.py: what the emitting surfaces share;
* the kinds, one module each: parallelograms.py (emissive quads that are parallelograms and
  4-corner Area lights: spherical rectangles, Urena et al. 2013, for rectangles), triangles.py
  (emissive mesh triangles: spherical triangles, Arvo 1995), spheres.py (emissive implicit
  spheres: cone from outside, area from inside), polygons.py (disk/ellipse Area lights and quads
  that are not parallelograms: area), points.py (point and spot lights), distant.py (suns and the
  world);
* emitters.py: a scene's emitters gathered per kind; selection.py: the pmfs that pick a light
  (by power, or the light tree); light_set.py: `LightSet`, the scene's lights, their selection
  and the maps from emissive primitives to lights (MIS);
* seen.py: point, spot and sun lights that mirror and glass rays meet.
"""
from .light_set import LightSample, LightSet

__all__ = ["LightSample", "LightSet"]
