"""Caustic photon mapping beside the path tracer (docs/photons.md): light paths L S+ D traced from
the lights, stored where they first reach a non-specular surface, and gathered at the first
non-specular vertex of camera paths, with a radius that shrinks pass after pass (progressive
photon mapping, Knaus & Zwicker 2011; the schedule of SPPM, Hachisuka & Jensen 2009).

* targets.py: the bounding spheres of the specular objects, which photons are aimed at;
* emission.py: photons leaving the lights, aimed at those spheres, with their flux;
* tracing.py: photons through the specular surfaces until they reach a non-specular one;
* photon_map.py: a batch's stored photons in a grid per pass (BatchMaps), the density estimate,
  the radius schedule;
* gather.py: the search and the sums of the density estimate (NumPy), gather_jit.py: its numba twin;
* caustics.py: `CausticPhotons`, what the path tracer asks for: the map of a pass (a function of
  the seed and the pass number only), cached.
"""
from .caustics import CausticPhotons, passes_of

__all__ = ["CausticPhotons", "passes_of"]
