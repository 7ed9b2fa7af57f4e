"""The rough dielectric interface lobe (Walter et al. 2007, "Microfacet Models for Refraction
through Rough Surfaces") in the local shading frame, as Cycles' bsdf_microfacet.h computes it: the
formulas and conventions are described in engine/materials/dielectric.py, whose BSDFs use it.

`MicrofacetDielectric` works over per-hit alpha and eta arrays, for any BSDF with a dielectric
interface (the Glass and Refraction BSDFs; a transmitting Principled BSDF).
"""
from __future__ import annotations

import numpy as np

from ..core.vec import dot, normalize
from .glossy import fresnel_dielectric
from .microfacet import BECKMANN, D, GGX, LAMBDA, SAMPLE_VNDF, clamp_alpha
from .protocol import BSDFFlags, ShadingPoint

REFLECTED = BSDFFlags.GLOSSY | BSDFFlags.REFLECTION
REFRACTED = BSDFFlags.GLOSSY | BSDFFlags.TRANSMISSION
PASSED = BSDFFlags.DELTA | BSDFFlags.TRANSMISSION        # index-matched: straight through


def dielectric_alpha(roughness) -> np.ndarray:
    """alpha = roughness^2 (Cycles' Glass and Refraction nodes: saturated), floored at ALPHA_MIN."""
    return clamp_alpha(np.clip(np.asarray(roughness, dtype=np.float64), 0.0, 1.0) ** 2)


def refraction_eta(si: ShadingPoint, ior: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(eta = n_far / n_near, entering) at hits `si` of surfaces of IOR `ior` (per hit): the viewer
    is outside where wo faces the outward normal.  Without a medium stack the other side is air (the
    report's and Cycles' model); with one (engine/materials/media.py) the media the path is in."""
    entering = dot(si.wo, si.normal) > 0.0
    if si.media is None:
        return np.where(entering, ior, 1.0 / ior), entering
    return 1.0 / si.media.eta(entering, ior), entering


class RealFresnel:
    """(R, T) (3, N) each at wo.h = cos: Cycles' generalized Schlick in its "real Fresnel" mode with a
    coloured F0 and a transmission tint, the Principled BSDF's glass closure's
    (engine/materials/principled_glass.py): s = (F_d(cos, eta) - F0(eta)) / (1 - F0(eta)) clamped to
    [0, 1] (NaN: 1), R = f0 + (1 - f0) s, T = (1 - R) tint; eta (N,), f0 and tint (3, N).  A class
    rather than a closure so that the compiled lobe (engine/materials/dielectric_jit.py) reads its
    inputs and repeats it."""

    def __init__(self, eta: np.ndarray, f0: np.ndarray, tint: np.ndarray):
        self.eta, self.f0, self.tint = eta, f0, tint

    def __call__(self, cos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        eta = np.asarray(self.eta, dtype=np.float64)
        f0_real = ((eta - 1.0) / (eta + 1.0)) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (fresnel_dielectric(cos, self.eta) - f0_real) / (1.0 - f0_real)
        s = np.clip(np.nan_to_num(s, nan=1.0), 0.0, 1.0)
        r = self.f0 + (1.0 - self.f0) * s
        return r, (1.0 - r) * self.tint


class MicrofacetDielectric:
    """The microfacet interface lobe(s) in the local frame, vectorised over hits with per-hit alpha
    (isotropic), eta = n_far / n_near and distribution (beckmann: bool per hit, else GGX).
    reflection / transmission: which lobes exist (glass: both; Cycles' Refraction BSDF: transmission)."""

    compiled = None     # engine/materials/dielectric_jit.py when the render runs the lobe on numba

    def __init__(self, reflection: bool = True, transmission: bool = True):
        self.reflection, self.transmission = reflection, transmission

    def _compiles(self, fresnel, refraction_side=True) -> bool:
        """Whether the compiled twin computes these hits: the dielectric Fresnel or RealFresnel (GGX and
        Beckmann hits alike)."""
        return self.compiled is not None and (fresnel is None or isinstance(fresnel, RealFresnel)) and refraction_side

    def split(self, cos_h: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(R, T): the weights of the reflected and refracted lobe at a microfacet with wo.h = cos_h."""
        f = fresnel_dielectric(cos_h, eta)
        if not self.transmission:
            return f, np.zeros_like(f)
        if not self.reflection:                              # Cycles' MicrofacetFresnel::NONE refraction
            return np.zeros_like(f), np.where(f >= 1.0, 0.0, 1.0)
        return f, 1.0 - f

    @staticmethod
    def _terms(wo, wi, h, alpha, beckmann):
        """(D(h), Lambda(wo), Lambda(|wi|)) per hit, each distribution on its hits."""
        n = wo.shape[1]
        d, lo, li = np.empty(n), np.empty(n), np.empty(n)
        wi_up = np.stack([wi[0], wi[1], np.abs(wi[2])])
        for dist, mask in ((GGX, ~beckmann), (BECKMANN, beckmann)):
            sel = np.flatnonzero(mask)
            if not len(sel):
                continue
            a = alpha.take(sel)
            d[sel] = D[dist](h.take(sel, axis=1), a, a)
            lo[sel] = LAMBDA[dist](wo.take(sel, axis=1), a, a)
            li[sel] = LAMBDA[dist](wi_up.take(sel, axis=1), a, a)
        return d, lo, li

    @staticmethod
    def _jacobian(cos_ho, cos_hi, eta, refracted):
        """The density of wi per density of h (times 1 / wo.z in common): 1 / 4 for reflection,
        |wo.h| |wi.h| / (wi.h + wo.h / eta)^2 for refraction."""
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.abs(cos_ho * cos_hi) / (cos_hi + cos_ho / eta) ** 2
        return np.where(refracted, t, 0.25)

    @staticmethod
    def _g2(lo, li, separable):
        """Masking-shadowing: height-correlated 1 / (1 + Lambda(wo) + Lambda(wi)) (Cycles >= 3.5), or
        where `separable` (a bool per hit, or None) G1(wo) G1(wi) (Blender 3.4)."""
        g2 = 1.0 / (1.0 + lo + li)
        if separable is None or not np.any(separable):
            return g2
        return np.where(separable, 1.0 / ((1.0 + lo) * (1.0 + li)), g2)

    def sample(self, wo, alpha, eta, beckmann, u_lobe, u1, u2, refraction_side: bool = True, separable=None,
               fresnel=None):
        """(wi, weight, pdf, refracted, ok) per hit: wi (3, N) local, weight = (f cos / pdf) / tint,
        pdf per solid angle (lobe probability included), refracted: the sample went through, ok: a
        valid sample (wo above, wi on its lobe's side, a lobe with weight).  refraction_side=False
        keeps refracted directions that leave on the viewer's side (only for the albedo tables:
        engine/materials/glass_albedo.py).  fresnel: None (the dielectric Fresnel, `split`) or a
        function of wo.h giving the lobes' weights (R, T), each (N,) or coloured (3, N); coloured,
        the reflection is picked with probability mean(R) / mean(R + T) (Cycles' pdf_reflect) and
        the weight is (3, N)."""
        if self._compiles(fresnel, refraction_side):          # the lines below (numbers: dielectric_jit.py)
            if fresnel is not None:
                return self.compiled.sample_coloured(wo, alpha, eta, beckmann, u_lobe, u1, u2, separable, self.reflection,
                                                     self.transmission, fresnel)
            return self.compiled.sample(wo, alpha, eta, beckmann, u_lobe, u1, u2, separable, self.reflection,
                                        self.transmission)
        h = np.empty_like(wo)
        for dist, mask in ((GGX, ~beckmann), (BECKMANN, beckmann)):
            sel = np.flatnonzero(mask)
            if len(sel):
                a = alpha.take(sel)
                h[:, sel] = SAMPLE_VNDF[dist](wo.take(sel, axis=1), a, a, u1.take(sel), u2.take(sel))
        cos_ho = np.clip(dot(wo, h), 0.0, 1.0)
        r, t = self.split(cos_ho, eta) if fresnel is None else fresnel(cos_ho)
        total = _mean(r + t)
        with np.errstate(divide="ignore", invalid="ignore"):
            p_reflect = np.where(total > 0.0, _mean(r) / total, 0.0)
            cos_t = np.sqrt(np.maximum(0.0, 1.0 - (1.0 - cos_ho * cos_ho) / (eta * eta)))
        refracted = u_lobe >= p_reflect
        with np.errstate(divide="ignore", invalid="ignore"):
            through = -wo / eta + (cos_ho / eta - cos_t) * h
        wi = np.where(refracted, through, 2.0 * cos_ho * h - wo)
        wi = normalize(wi)
        ok = (wo[2] > 0.0) & (total > 0.0) & np.where(refracted, (wi[2] < 0.0) | (not refraction_side), wi[2] > 0.0)
        d, lo, li = self._terms(wo, wi, h, alpha, beckmann)
        cos_hi = dot(wi, h)
        lobe = np.where(refracted, 1.0 - p_reflect, p_reflect)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            common = d / wo[2] * self._jacobian(cos_ho, cos_hi, eta, refracted)
            pdf = np.where(ok, lobe * common / (1.0 + lo), 0.0)
            weight = np.where(ok, np.where(refracted, t, r) / lobe * (1.0 + lo) * self._g2(lo, li, separable), 0.0)
        return wi, np.nan_to_num(weight), np.nan_to_num(pdf), refracted, ok & (pdf > 0.0)

    def eval(self, wo, wi, alpha, eta, beckmann, separable=None, fresnel=None):
        """(f cos / tint, pdf) per hit for local directions wo (above) and wi (either side);
        fresnel as in `sample` (coloured: f cos is (3, N))."""
        if self._compiles(fresnel):                           # the lines below (numbers: dielectric_jit.py)
            if fresnel is not None:
                return self.compiled.eval_coloured(wo, wi, alpha, eta, beckmann, separable, self.reflection,
                                                   self.transmission, fresnel)
            return self.compiled.eval(wo, wi, alpha, eta, beckmann, separable, self.reflection, self.transmission)
        refracted = wi[2] < 0.0
        half = np.where(refracted, -(wo + eta * wi), wo + wi)
        length = np.sqrt(dot(half, half))
        h = half / np.where(length > 0.0, length, 1.0)
        h = h * np.where(h[2] < 0.0, -1.0, 1.0)                  # the microfacet faces the viewer's side
        cos_ho, cos_hi = dot(wo, h), dot(wi, h)
        ok = ((wo[2] > 0.0) & (wi[2] != 0.0) & (length > 0.0) & (cos_ho > 0.0)
              & np.where(refracted, cos_hi < 0.0, cos_hi > 0.0))
        if self.transmission and not self.reflection:
            ok &= refracted
        if not self.transmission:
            ok &= ~refracted
        r, t = self.split(np.clip(cos_ho, 0.0, 1.0), eta) if fresnel is None else fresnel(np.clip(cos_ho, 0.0, 1.0))
        total = _mean(r + t)
        d, lo, li = self._terms(wo, wi, h, alpha, beckmann)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            p_reflect = np.where(total > 0.0, _mean(r) / total, 0.0)
            lobe = np.where(refracted, 1.0 - p_reflect, p_reflect)
            common = d / wo[2] * self._jacobian(cos_ho, cos_hi, eta, refracted)
            pdf = np.where(ok, lobe * common / (1.0 + lo), 0.0)
            f_cos = np.where(ok, np.where(refracted, t, r) * common * self._g2(lo, li, separable), 0.0)
        return np.nan_to_num(f_cos), np.nan_to_num(pdf)


def _mean(x: np.ndarray) -> np.ndarray:
    """x (N,) itself, or the channel mean of coloured weights (3, N) (Cycles' average)."""
    return x if x.ndim == 1 else x.mean(axis=0)
