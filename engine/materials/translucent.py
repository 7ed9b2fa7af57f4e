"""The Translucent BSDF (Cycles' bsdf_diffuse.h, bsdf_translucent): diffuse transmission,
f = colour / pi for directions on the far side of the shading normal (0 on the viewer's), sampled
cosine-weighted about -n, so that f cos / pdf is the colour.  Light samples reach it from the far
side (engine/integrators/path_tracer.py direct_light); no medium change (a thin sheet)."""
from __future__ import annotations

import numpy as np

from ..core.vec import dot
from ..sampling.warps import cosine_directions
from .protocol import BSDF, BSDFFlags, BSDFSample, ShadingPoint

LOBE = BSDFFlags.DIFFUSE | BSDFFlags.TRANSMISSION


class Translucent(BSDF):
    """Diffuse transmission with transmittance si.color."""
    flags = LOBE

    def sample(self, si: ShadingPoint, u_lobe, u) -> BSDFSample:
        wi = cosine_directions(u[0], u[1], -si.n)
        return BSDFSample(wi, si.color, self.pdf(si, wi), np.full(len(si), LOBE, dtype=np.int8))

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        """|cos| / pi on the far side of the shading normal, 0 on the viewer's."""
        return np.maximum(-dot(wi, si.n), 0.0) * (1.0 / np.pi)

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pdf = self.pdf(si, wi)
        return si.color * pdf, pdf
