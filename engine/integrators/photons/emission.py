"""Photons leaving the lights: a light picked by its flux, a ray from it by the light's own
sample_emission (engine/lights/protocol.py), aimed at the specular objects' bounding spheres
(engine/lights/aim.py), each carrying the flux

    Phi = Le |cos theta| / (P(light) pdf_pos pdf_dir N)

so that the N photons' fluxes sum, in expectation, to the flux the lights send towards the targets
(all their flux without targets).  Photons of zero flux (the back of a one-sided light, outside a
spot's cone) are dropped before tracing.  Each photon starts a little off its light, along the
normal of the side it leaves (the light set's LIGHT_OFFSET, relative to the coordinates), so that
the emitter's own surface never stops it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.vec import dot, max_abs3
from ...lights.light_set import LIGHT_OFFSET


@dataclass
class Emitted:
    origin: np.ndarray      # (3, M)
    direction: np.ndarray   # (3, M)
    flux: np.ndarray        # (3, M) [W]
    emitted: int            # N: the photons drawn, those of zero flux included


def light_flux(lights) -> np.ndarray:
    """(L,) the flux of every light of the light set (engine/lights/light_set.py), in light numbers."""
    parts = [np.asarray(kind.power(), dtype=np.float64) for kind in lights.kinds]
    return np.concatenate(parts) if parts else np.zeros(0)


def emit(lights, n: int, rng, targets=None) -> Emitted:
    """n photons from `lights`, picked by flux, aimed at `targets` (or None: unaimed)."""
    flux = np.maximum(light_flux(lights), 0.0)
    total = flux.sum()
    if n <= 0 or total <= 0:
        return Emitted(np.zeros((3, 0)), np.zeros((3, 0)), np.zeros((3, 0)), max(n, 0))
    cdf = np.cumsum(flux) / total
    light = np.minimum(np.searchsorted(cdf, rng.random(n), side="right"), len(flux) - 1)
    u = rng.random((4, n))
    origins, directions, fluxes = [], [], []
    for kind in lights.kinds:
        mine = np.flatnonzero((light >= kind.first) & (light < kind.first + kind.count))
        if not len(mine):
            continue
        idx = light.take(mine) - kind.first
        e = kind.sample_emission(idx, *(u[j].take(mine) for j in range(4)), targets=targets)
        p_light = flux.take(light.take(mine)) / total
        cos = np.abs(dot(e.direction, e.normal))
        with np.errstate(divide="ignore", invalid="ignore"):
            phi = e.radiance * (cos / (p_light * e.pdf_pos * e.pdf_dir * n))
        phi = np.where(np.isfinite(phi), phi, 0.0)
        origins.append(e.origin + (LIGHT_OFFSET * np.maximum(max_abs3(e.origin), 1.0)) * e.normal)
        directions.append(e.direction)
        fluxes.append(phi)
    o, d, phi = (np.concatenate(a, axis=1) for a in (origins, directions, fluxes))
    keep = np.flatnonzero(phi.max(axis=0) > 0.0)
    return Emitted(o.take(keep, axis=1), d.take(keep, axis=1), phi.take(keep, axis=1), n)
