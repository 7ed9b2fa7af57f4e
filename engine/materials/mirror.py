"""The perfect mirror, report 2.5.3: all light leaves in the mirror direction (eq. 2.20), with
weight = the reflectance colour (eq. 2.15-2.16).  `BlurredMirror` is the same mirror after Filter
Glossy has blurred it (engine/integrators/delta_blur.py): Cycles' GGX (or Beckmann) closure of
alpha 0 with the alpha raised to the path's floor."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from .glossy import MicrofacetReflection
from .microfacet import BECKMANN, GGX
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


class BlurredMirror(MicrofacetReflection):
    """The mirror materials as Cycles' Glossy BSDF at roughness 0 (weight the colour, no Fresnel,
    isotropic, no energy compensation: Cycles sets that up from the closure's own roughness 0, before
    the blur), whose alpha is only si.alpha_floor (at least ALPHA_MIN).  Its hits are the mirror
    hits of paths with an alpha floor (engine/integrators/delta_blur.py); a roughness texture or
    program on a mirror is ignored, as the sharp mirror ignores it."""
    roughness_input = None

    def __init__(self, materials, settings):
        super().__init__([SimpleNamespace(roughness=0.0, anisotropy=0.0, fresnel="none", multiscatter=False, ior=m.ior,
                                          distribution=BECKMANN if getattr(m, "distribution", GGX) == BECKMANN
                                          else GGX) for m in materials], settings)

    def use_backend(self, backends: dict) -> None:
        """The compiled GGX (engine/materials/microfacet_jit.py) where the render's own kernels run
        compiled: blurred mirrors come with no Glossy material that would ask for it."""
        super().use_backend({**backends, "glossy": backends.get("wavefront", "numpy")})
