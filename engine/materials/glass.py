"""Smooth glass, report 2.5.4: the Fresnel reflectance R (eq. 2.17, Schlick or exact,
engine/materials/fresnel.py) chooses reflection (eq. 2.20) or refraction (eq. 2.21-2.24)
stochastically, so both weights are the tint (R / R and T / T); total internal reflection has
R = 1.  By default every surface separates its IOR from air, as the report and Cycles do; with
a medium stack (nested dielectrics, engine/materials/media.py) from the medium the path is in."""
from __future__ import annotations

import numpy as np

from ..core.vec import dot
from .fresnel import FRESNEL
from .protocol import BSDF, BSDFFlags, BSDFSample, ShadingPoint, delta_eval
from .specular import reflect, refract, refract_cos, specular_normal

REFLECTED = BSDFFlags.DELTA | BSDFFlags.REFLECTION
TRANSMITTED = BSDFFlags.DELTA | BSDFFlags.TRANSMISSION


class SmoothGlass(BSDF):
    """Delta reflection and transmission with tint si.color and the materials' IORs."""
    flags = REFLECTED | TRANSMITTED

    def __init__(self, materials, settings):
        self.ior = np.array([m.ior for m in materials], dtype=np.float64)
        self.fresnel = FRESNEL[settings.fresnel]

    jit = None          # the sampling compiled (engine/materials/glass_jit.py), when the render runs numba

    def use_backend(self, backends: dict) -> None:
        self.jit = None
        if backends.get("wavefront", "numpy") == "numba":
            from . import glass_jit
            self.jit = glass_jit

    def sample(self, si: ShadingPoint, u_lobe, u=None) -> BSDFSample:
        """u_lobe < R reflects, else the ray refracts; a refraction moves the path into or out
        of the surface's medium on si.media."""
        if self.jit is not None and si.media is None and not si.smooth:    # the lines below, the same numbers
            cos_i, cos_t, eta, tir = self.jit.cosines(si.wo, si.normal, si.material, self.ior)
            wi, pdf, flags = self.jit.directions(si.wo, si.n, cos_i, cos_t, eta, self.fresnel(cos_i, cos_t, eta, tir),
                                                 u_lobe, REFLECTED, TRANSMITTED)
            return BSDFSample(wi, si.color, pdf, flags)
        facing = specular_normal(si)
        d = -si.wo                                                        # the ray's direction
        cos_in = dot(d, si.normal)                                        # its sign: entering or leaving
        if si.smooth:
            cos_in = np.copysign(np.abs(dot(d, facing)), cos_in)
        ior = self.ior.take(si.material)
        cos_i = np.abs(cos_in)
        entering = cos_in < 0.0
        if si.media is None:
            eta = np.where(entering, 1.0 / ior, ior)       # n1 / n2, air on the other side
        else:
            eta = si.media.eta(entering, ior)
        cos_t, tir = refract_cos(cos_i, eta)
        fresnel = self.fresnel(cos_i, cos_t, eta, tir)
        reflected = u_lobe < fresnel
        wi = np.empty_like(d)
        sel = np.flatnonzero(reflected)
        if len(sel):
            wi[:, sel] = reflect(d.take(sel, axis=1), facing.take(sel, axis=1))
        through = np.flatnonzero(~reflected)
        if len(through):
            wi[:, through] = refract(d.take(through, axis=1), facing.take(through, axis=1), cos_i.take(through),
                                     cos_t.take(through), eta.take(through))
        if si.media is not None:
            si.media.cross(through, entering, ior)
        flags = np.where(reflected, np.int8(REFLECTED), np.int8(TRANSMITTED))
        return BSDFSample(wi, si.color, np.where(reflected, fresnel, 1.0 - fresnel), flags)

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return delta_eval(si, wi)

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        return np.zeros(wi.shape[1])
