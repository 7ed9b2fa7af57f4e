"""The Lambertian (ideal diffuse) BSDF, report 2.5.2: f = rho / pi (eq. 2.13a), sampled by the
cosine-weighted hemisphere about the shading normal (eq. 2.13b), so that f cos / pdf is exactly
the albedo rho (eq. 2.14)."""
from __future__ import annotations

import numpy as np

from ..core.vec import dot
from ..sampling.warps import cosine_directions
from .protocol import BSDF, BSDFFlags, BSDFSample, ShadingPoint

LOBE = BSDFFlags.DIFFUSE | BSDFFlags.REFLECTION


class Lambertian(BSDF):
    """Diffuse reflection with albedo si.color."""
    flags = LOBE
    cosine_pdf = True                 # pdf below (engine/materials/protocol.py BSDF.cosine_pdf)

    jit = None          # the sampling compiled (engine/materials/lambert_jit.py), when the render runs numba

    def use_backend(self, backends: dict) -> None:
        self.jit = None
        if backends.get("wavefront", "numpy") == "numba":
            from . import lambert_jit
            self.jit = lambert_jit

    def sample(self, si: ShadingPoint, u_lobe, u) -> BSDFSample:
        if self.jit is not None:                        # the lines below in one loop, the same numbers
            wi, pdf = self.jit.sample(u[0], u[1], si.n)
            return BSDFSample(wi, si.color, pdf, np.full(len(si), LOBE, dtype=np.int8))
        wi = cosine_directions(u[0], u[1], si.n)                          # eq. 2.13b
        # f cos / pdf = (rho / pi) cos / (cos / pi) = rho (eq. 2.14): the colour itself, exactly.
        return BSDFSample(wi, si.color, self.pdf(si, wi), np.full(len(si), LOBE, dtype=np.int8))

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        """cos / pi on the shading normal's side, 0 below."""
        return np.maximum(dot(wi, si.n), 0.0) * (1.0 / np.pi)

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pdf = self.pdf(si, wi)
        return si.color * pdf, pdf                                        # (rho / pi) cos = rho pdf

    def lambert_albedo(self, si: ShadingPoint) -> np.ndarray:
        return si.color
