"""The perfect mirror, report 2.5.3: all light leaves in the mirror direction (eq. 2.20), with
weight = the reflectance colour (eq. 2.15-2.16)."""
from __future__ import annotations

import numpy as np

from .protocol import BSDF, BSDFFlags, BSDFSample, ShadingPoint, delta_eval
from .specular import reflect, specular_normal

LOBE = BSDFFlags.DELTA | BSDFFlags.REFLECTION


class PerfectMirror(BSDF):
    """Delta reflection with reflectance si.color."""
    flags = LOBE

    def sample(self, si: ShadingPoint, u_lobe, u=None) -> BSDFSample:
        n = len(si)
        wi = reflect(-si.wo, specular_normal(si))                         # eq. 2.20
        return BSDFSample(wi, si.color, np.ones(n), np.full(n, LOBE, dtype=np.int8))

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return delta_eval(si, wi)

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        return np.zeros(wi.shape[1])
