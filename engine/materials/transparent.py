"""The Transparent BSDF (Cycles' bsdf_transparent.h): light passes straight through, unbent, with
weight = the colour; the path stays in the medium it was in (no refraction, no medium change).

Shadow rays are not let through (Cycles' "transparent shadows" are not modelled): a transparent
surface blocks them as any surface does, and the light behind it is found by the paths that pass
through it, whose emission counts with weight 1 after this delta bounce, so the estimate stays
unbiased (engine/integrators/path_tracer.py).  The straight-through bounce counts towards the depth
limit (Cycles keeps a separate transparent bounce limit).  Its flags carry STRAIGHT, as the
Principled BSDF's alpha does (engine/materials/principled.py): a camera ray goes on as a camera ray,
so what it meets behind the surface is seen as directly as Cycles shows it."""
from __future__ import annotations

import numpy as np

from .protocol import BSDF, BSDFFlags, BSDFSample, ShadingPoint, delta_eval

LOBE = BSDFFlags.DELTA | BSDFFlags.TRANSMISSION | BSDFFlags.STRAIGHT


class Transparent(BSDF):
    """Delta transmission wi = -wo with weight si.color."""
    flags = LOBE

    def sample(self, si: ShadingPoint, u_lobe, u=None) -> BSDFSample:
        n = len(si)
        return BSDFSample(-si.wo, si.color, np.ones(n), np.full(n, LOBE, dtype=np.int8))

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return delta_eval(si, wi)

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        return np.zeros(wi.shape[1])
