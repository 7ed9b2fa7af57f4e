"""The Principled BSDF v1's transmission (Blender 3.x) as Cycles 3.4 sets it up (its
kernel/svm/closure.h, case CLOSURE_BSDF_PRINCIPLED_ID, "BSDF" block; kernel/closure/
bsdf_microfacet.h and bsdf_microfacet_multi.h; a public source: blender/cycles at tag v3.4.0,
src/kernel/), for engine/materials/principled_v1.py.

The glass weight is W_g = transmission x (1 - metallic) (both clamped to [0, 1]); eta = IOR
entering, 1 / IOR leaving (or the media of the path's medium stack, engine/materials/media.py,
which a refraction updates); cspec0 = mix(1, base colour, specular tint) clamped to [0, 1];
F = F_d(wo.n, eta), the dielectric Fresnel at the shading normal (the "macro" Fresnel).

* The node's distribution "GGX", or any roughness <= 0.05: two closures of single-scattering GGX
  with the separable masking G1(wo) G1(wi):
  - reflection, weight W_g x F: GGX reflection (alpha = roughness^2) with the interpolated Fresnel
    mix(cspec0, 1, (F_d(wi.h, eta) - F0) / (1 - F0)) (as the specular lobe's, at this eta);
  - refraction, weight W_g x base x max(1e-4, 1 - F): GGX refraction without a Fresnel factor (a
    microfacet in total internal reflection refracts nothing), alpha = t_r^2 with the
    transmission roughness t_r = 1 - (1 - roughness)(1 - Transmission Roughness) for "GGX", the
    roughness for "Multiscatter GGX" (3.4 still has the Transmission Roughness input: it only
    reaches the "GGX" glass).
  Cycles' sampling weights: the reflection's W_g F x mean(mix(cspec0, 1, s(wo.n))), the
  refraction's mean of its weight.
* "Multiscatter GGX" above roughness 0.05: one closure of weight W_g, Heitz et al.'s random walk
  on the glass microsurface (2016), its reflections F_d x the interpolated Fresnel colour, each
  refraction tinted by the base colour.  We approximate it as engine/materials/dielectric.py does
  the 3.4 Glass BSDF's: the walk's single-scattering term (GGX glass, height-correlated G2, R =
  F_d(wi.h) x mix(cspec0, 1, s(h)), T = (1 - F_d) x base) times Cycles 4.x's energy compensation
  1 + F_ms (1 - E) / E from the glass albedo tables, F_ms from the base colour.  Sampling weight:
  W_g x mean(mix(cspec0, 1, s(wo.n))) (bsdf_microfacet_fresnel_color).

Filter Glossy raises the reflection, refraction and multiscatter glass alphas to at least
ShadingPoint.alpha_floor (Cycles 3.4's bsdf_blur, docs/cycles34-filter-glossy.md; `alphas`).

Either way the light crossing the glass is tinted by the base colour at each refraction (twice
through a ball: base^2, where 4.x's glass tints by sqrt(base) each time).  3.4's refraction eval
returns a value for any pair of directions on opposite sides, also where no microfacet refracts
one into the other (which its sampler never draws); ours is 0 there.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import dot
from .dielectric import energy_scale
from .dielectric_lobe import MicrofacetDielectric, dielectric_alpha, refraction_eta
from .glossy import fresnel_dielectric

SINGLE_SCATTER_ROUGHNESS = 0.05     # closure.h: at or below it the glass is single-scatter GGX
REFRACTION_FLOOR = 1e-4             # closure.h: max(0.0001, 1 - fresnel), for MNEE
WEIGHT_CUTOFF = 1e-5                # Cycles' CLOSURE_WEIGHT_CUTOFF
CLOSURES = ("glass reflection", "glass refraction", "multiscatter glass")


def interpolated_fresnel(cos, eta, cspec0):
    """mix(cspec0, 1, (F_d(cos, eta) - F0) / (1 - F0)) (3, N) (Cycles' interpolate_fresnel_color)."""
    f0 = fresnel_dielectric(np.ones_like(cos), eta)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(f0 < 1.0, (fresnel_dielectric(cos, eta) - f0) / (1.0 - f0), 1.0)
    return cspec0 * (1.0 - s) + s


class PrincipledV1Glass:
    """The three possible glass closures of every material (weights 0 where a material has none)."""

    def __init__(self, materials, params):
        m = len(materials)

        def column(values):
            return np.array(values, dtype=np.float64).reshape(m)
        metallic = column([min(max(p.metallic, 0.0), 1.0) for p in params])
        self.transmission = column([min(max(p.transmission, 0.0), 1.0) for p in params])
        self.weight = self.transmission * (1.0 - metallic)
        self.any = bool(np.any(self.weight > WEIGHT_CUTOFF))
        self.specular_tint = column([p.specular_tint for p in params])
        self.ior = column([max(getattr(x, "ior", 1.45), 1e-5) for x in materials])
        roughness = column([min(max(getattr(x, "roughness", 0.5), 0.0), 1.0) for x in materials])
        multi = column([bool(getattr(x, "multiscatter", False)) for x in materials]).astype(bool)
        self.multiscatter = multi & (roughness > SINGLE_SCATTER_ROUGHNESS)
        t_r = column([min(max(p.transmission_roughness, 0.0), 1.0) for p in params])
        self.roughness = roughness
        self.alpha = dielectric_alpha(roughness)
        self.alpha_refraction = dielectric_alpha(np.where(multi, roughness, 1.0 - (1.0 - roughness) * (1.0 - t_r)))
        self.reflect = MicrofacetDielectric(reflection=True, transmission=False)
        self.refract = MicrofacetDielectric(reflection=False, transmission=True)
        self.both = MicrofacetDielectric(reflection=True, transmission=True)

    def cspec0(self, si):
        tint = self.specular_tint.take(si.material)
        return np.clip(si.color * tint + (1.0 - tint), 0.0, 1.0)

    def closures(self, si):
        """(weights: three (3, N) closure weights in CLOSURES order, sample (3, N) Cycles' sampling
        weights) at the hits."""
        mat = si.material
        n = len(si)
        w = self.weight.take(mat)
        on = w > WEIGHT_CUTOFF
        eta, _ = refraction_eta(si, self.ior.take(mat))
        cos_o = np.clip(dot(si.wo, si.n), 0.0, 1.0)
        f = fresnel_dielectric(cos_o, eta)
        multi = self.multiscatter.take(mat)
        single = on & ~multi
        ones = np.ones((3, n))
        w_reflect = np.where(single, w * f, 0.0) * ones
        w_refract = np.where(single, 1.0, 0.0) * np.clip(si.color, 0.0, None) * (w * np.maximum(REFRACTION_FLOOR, 1.0 - f))
        w_multi = np.where(on & multi, w, 0.0) * ones
        weights = [np.where(x.mean(axis=0) >= WEIGHT_CUTOFF, x, 0.0) for x in (w_reflect, w_refract, w_multi)]
        colour = interpolated_fresnel(cos_o, eta, self.cspec0(si)).mean(axis=0)
        sample = np.stack([weights[0].mean(axis=0) * colour, weights[1].mean(axis=0), weights[2].mean(axis=0) * colour])
        return weights, sample

    def _setup(self, si):
        mat = si.material
        eta, entering = refraction_eta(si, self.ior.take(mat))
        return mat, eta, entering

    def alphas(self, si):
        """(reflection alpha, refraction alpha, roughness of the multiscatter glass's albedo tables) (N,)
        at the hits: the material's, the alphas at least si.alpha_floor (Filter Glossy: Cycles 3.4's
        bsdf_blur raises the alphas of the GGX reflection, GGX refraction and multi-GGX glass closures,
        docs/cycles34-filter-glossy.md); the tables' roughness follows a raised alpha (3.4's random
        walk runs on it), the single-or-multiscatter choice keeps the material's roughness."""
        mat = si.material
        alpha, alpha_t, rough = self.alpha.take(mat), self.alpha_refraction.take(mat), self.roughness.take(mat)
        floor = si.alpha_floor
        if floor is None:
            return alpha, alpha_t, rough
        rough = np.where(floor > alpha, np.sqrt(floor), rough)
        return np.maximum(alpha, floor), np.maximum(alpha_t, floor), rough

    def _multi_fresnel(self, eta, cspec0, base):
        def split(cos):
            f = fresnel_dielectric(cos, eta)
            return f * interpolated_fresnel(cos, eta, cspec0), (1.0 - f) * base
        return split

    def eval(self, code, si, wo_l, wi_l):
        """(f cos (3, N) without the closure weight, pdf (N,)) of closure `code` (local directions)."""
        _, eta, _ = self._setup(si)
        alpha, alpha_t, rough = self.alphas(si)
        beckmann = np.zeros(len(si), dtype=bool)
        separable = np.ones(len(si), dtype=bool)
        if code == 0:
            cspec0 = self.cspec0(si)
            f, pdf = self.reflect.eval(wo_l, wi_l, alpha, eta, beckmann, separable,
                                       fresnel=lambda c: (interpolated_fresnel(c, eta, cspec0), np.zeros_like(cspec0)))
            return f, pdf
        if code == 1:
            f, pdf = self.refract.eval(wo_l, wi_l, alpha_t, eta, beckmann, separable)
            return f[None, :] * np.ones((3, 1)), pdf
        base = np.clip(si.color, 0.0, 1.0)
        f, pdf = self.both.eval(wo_l, wi_l, alpha, eta, beckmann,
                                fresnel=self._multi_fresnel(eta, self.cspec0(si), base))
        return f * energy_scale(rough, wo_l[2], eta, base), pdf

    def sample(self, code, si, wo_l, u_fresnel, u1, u2):
        """(wi_l (3, N), refracted (N,), entering (N,)) drawn from closure `code` (its own density)."""
        _, eta, entering = self._setup(si)
        alpha, alpha_t, _ = self.alphas(si)
        beckmann = np.zeros(len(si), dtype=bool)
        if code == 0:
            lobe = self.reflect
        elif code == 1:
            lobe, alpha = self.refract, alpha_t
        else:
            lobe = self.both
        fresnel = self._multi_fresnel(eta, self.cspec0(si), np.clip(si.color, 0.0, 1.0)) if code == 2 else None
        wi_l, _, _, refracted, ok = lobe.sample(wo_l, alpha, eta, beckmann, u_fresnel, u1, u2, fresnel=fresnel)
        return np.where(ok, wi_l, 0.0), refracted & ok, entering
