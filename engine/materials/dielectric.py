"""Rough dielectric interfaces: microfacet reflection and refraction (Walter et al. 2007, "Microfacet
Models for Refraction through Rough Surfaces") as Cycles' Glass and Refraction BSDFs render them
(its bsdf_microfacet.h, a public source: blender/cycles src/kernel/closure/).

In the local shading frame (z = the shading normal on the viewer's side, wo.z > 0) with
eta = n_far / n_near (the IOR beyond the surface over the viewer's, Cycles' `bsdf->ior`):

* A microfacet normal h is drawn from the visible normals of wo (GGX: Heitz 2018, Beckmann: Heitz &
  d'Eon 2014; engine/materials/microfacet.py).  Its Fresnel F = F(wo.h, eta) (1 under total internal
  reflection) splits it: reflection with probability R / (R + T), else refraction, R = F and
  T = 1 - F for glass; R = 0 and T = 1 (0 under total internal reflection) for the Refraction BSDF.
* Reflection: wi = 2 (wo.h) h - wo, f cos = R D G2 / (4 wo.z).
  Refraction: wi = -wo / eta + (wo.h / eta - cos_t) h, f cos = T D G2 |wo.h| |wi.h| /
  (wo.z (wi.h + wo.h / eta)^2), the generalised half vector h = -(wo + eta wi) / |...| (facing z).
  The pdfs are the same with G1(wo) for G2 and times the lobe's probability, so that the weight
  f cos / pdf = (R or T) / P(lobe) x G2 / G1(wo), computed as that ratio.
* No 1 / eta^2 radiance scaling: Cycles' weight of a refraction is T / P(lobe) x G2 / G1 (and its
  smooth glass's is the tint, engine/materials/glass.py), so f(wo, wi) eta_near^2 = f(wi, wo) eta_far^2
  (a BTDF's generalised reciprocity, Veach's thesis ch. 5, here for the BTDF without the radiance factor).
* Energy compensation ("multi_ggx", Cycles 4.x microfacet_ggx_preserve_energy): both lobes are scaled
  by 1 + F_ms (1 - E) / E, E = E(roughness, wo.z, eta) the albedo of the GGX dielectric with F = the
  dielectric Fresnel (engine/materials/glass_albedo.py), F_ms = c E_avg / (1 - c (1 - E_avg)) with
  c the tint (Cycles' F_ss is the transmission tint): 1 / E for white glass.

Blender 3.4 (Scene.cycles_version before 3.5) multiplies separable G1(wo) G1(wi) instead of G2.
Cycles' glass is isotropic (alpha_y = alpha_x).  Interfaces with |eta - 1| < INDEX_MATCHED pass
light straight through (a delta transmission), as Cycles and engine/materials/fresnel.py do.

The lobe alone, `MicrofacetDielectric` over per-hit alpha and eta arrays, is in
engine/materials/dielectric_lobe.py, for any BSDF with a dielectric interface (the Glass and
Refraction BSDFs here; a transmitting Principled BSDF).  An image texture on the roughness
(Material.input_textures) gives each textured hit its own alpha and table roughness (`_rough`).
"""
from __future__ import annotations

import numpy as np

from ..core.backend import JIT_MODULES, NUMBA
from ..core.vec import dot, normalize
from . import glass_albedo
from .dielectric_lobe import PASSED, REFLECTED, REFRACTED, MicrofacetDielectric, dielectric_alpha, refraction_eta
from .fresnel import INDEX_MATCHED
from .microfacet import BECKMANN, GGX, shading_frame, to_local, to_world
from .protocol import BSDF, BSDFSample, ShadingPoint, delta_eval
from .specular import refract, refract_cos, specular_normal, specular_normal_at
from .textures import per_hit, textured_mask

MULTI_GGX = "multi_ggx"
HEIGHT_CORRELATED_SINCE = (3, 5)        # Cycles' G2 before: separable G1 G1


def energy_scale(roughness, mu, eta, tint) -> np.ndarray:
    """Cycles 4.x's multiscatter factor (3, N) of the GGX glass: 1 + F_ms (1 - E) / E, E and E_avg
    from engine/materials/glass_albedo.py at (roughness, mu = wo.z, eta), F_ms from the tint.  NaN
    at a point off the tables (a NaN roughness, mu or eta, or an infinite eta: a NaN coordinate,
    which no table index is), where the tables are not read (dielectric_jit.energy_scale the same)."""
    mu = np.clip(mu, 0.0, 1.0)
    off = np.isnan(roughness + mu) | ~np.isfinite(eta)
    if off.any():                               # read at a point on the tables there, then NaN
        roughness, mu, eta = np.where(off, 0.0, roughness), np.where(off, 0.0, mu), np.where(off, 1.0, eta)
    e = glass_albedo.albedo(roughness, mu, eta)
    e_avg = glass_albedo.average_albedo(roughness, eta)
    f_ms = tint * e_avg / (1.0 - tint * (1.0 - e_avg))
    with np.errstate(divide="ignore", invalid="ignore"):
        missing = np.where(e > 0.0, (1.0 - e) / e, 0.0)
    scale = 1.0 + f_ms * missing
    return np.where(off, np.nan, scale) if off.any() else scale


class RoughDielectric(BSDF):
    """Cycles' Glass BSDF with roughness > 0 (reflection and refraction), or its Refraction BSDF
    (`reflection = False`): per material alpha, IOR, distribution and compensation ("multi_ggx",
    GGX glass only, as Cycles).  The tint si.color multiplies both lobes."""
    reflection = True
    flags = REFLECTED | REFRACTED | PASSED

    def __init__(self, materials, settings, cycles_version=(5, 0)):
        self.ior = np.array([max(m.ior, 1e-5) for m in materials], dtype=np.float64)
        self.roughness = np.array([min(max(m.roughness, 0.0), 1.0) for m in materials], dtype=np.float64)
        self.alpha = dielectric_alpha(self.roughness)
        self.beckmann = np.array([getattr(m, "distribution", GGX) == BECKMANN for m in materials], dtype=bool)
        self.compensate = np.array([getattr(m, "distribution", GGX) == MULTI_GGX and self.reflection
                                    for m in materials], dtype=bool)
        # Blender 3.4's single-scatter glass: separable G1 G1 (its compensated one, a random walk
        # then, is approximated by 4.x's compensation of the height-correlated lobe).
        self.separable = np.full(len(materials), tuple(cycles_version) < HEIGHT_CORRELATED_SINCE) & ~self.compensate
        self.lobe = MicrofacetDielectric(reflection=self.reflection, transmission=True)

    def use_backend(self, backends: dict) -> None:
        """The GGX lobe's sample and eval compiled (engine/materials/dielectric_jit.py, the same
        numbers) when the render runs the rough glass, refraction or Filter Glossy's blurred glass
        on numba."""
        if any(backends.get(k) == NUMBA for k in JIT_MODULES["materials.dielectric_jit"]):
            from . import dielectric_jit
            self.lobe.compiled = dielectric_jit
        else:
            self.lobe.compiled = None
        super().use_backend(backends)

    def _rough(self, si: ShadingPoint) -> tuple[np.ndarray, np.ndarray]:
        """(roughness, alpha) (N,) at the hits: the material's, a roughness texture's where it has one."""
        mat = si.material
        roughness, alpha = self.roughness.take(mat), self.alpha.take(mat)
        textured = textured_mask(si, "roughness")
        if textured is None:
            return roughness, alpha
        r = np.clip(per_hit(si, self.roughness, "roughness"), 0.0, 1.0)
        return np.where(textured, r, roughness), np.where(textured, dielectric_alpha(r), alpha)

    def _local(self, si: ShadingPoint):
        mat = si.material
        eta, entering = refraction_eta(si, self.ior.take(mat))
        n = specular_normal_at(si)
        x, y = shading_frame(n) if self.lobe.compiled is None else self.lobe.compiled.frame(n)   # the same numbers
        return mat, eta, entering, (x, y, n)

    def _scale(self, si, mat, mu, eta):
        """The compensation factor (3, N) where the material compensates, else None."""
        on = self.compensate.take(mat)
        if not on.any():
            return None
        scale = energy_scale if self.lobe.compiled is None else self.lobe.compiled.energy_scale     # the same numbers
        return np.where(on, scale(self._rough(si)[0], mu, eta, si.color), 1.0)

    def _alpha(self, si: ShadingPoint, mat):
        """Each hit's alpha (a roughness texture's where it has one: `_rough`), at least
        si.alpha_floor (Filter Glossy, engine/integrators/light_paths.py)."""
        alpha = self._rough(si)[1]
        return alpha if si.alpha_floor is None else np.maximum(alpha, si.alpha_floor)

    def sample(self, si: ShadingPoint, u_lobe, u) -> BSDFSample:
        """A refraction moves the path into or out of the surface's medium on si.media."""
        mat, eta, entering, frame = self._local(si)
        wo = to_local(si.wo, *frame)
        matched = np.abs(eta - 1.0) < INDEX_MATCHED
        wi_l, weight, pdf, refracted, ok = self.lobe.sample(wo, self._alpha(si, mat), eta, self.beckmann.take(mat),
                                                            u_lobe, u[0], u[1], separable=self.separable.take(mat))
        wi = normalize(to_world(wi_l, *frame))
        value = si.color * weight
        scale = self._scale(si, mat, wo[2], eta)
        if scale is not None:
            value = value * scale
        flags = np.where(refracted, np.int8(REFRACTED), np.int8(REFLECTED))
        if matched.any():                     # index-matched: straight through, the tint as weight
            wi = np.where(matched, -si.wo, wi)
            value = np.where(matched, si.color, value)
            pdf = np.where(matched, 1.0, pdf)
            flags = np.where(matched, np.int8(PASSED), flags)
            refracted = refracted | matched
            ok = ok | matched
        value = np.where(ok, value, 0.0)
        if si.media is not None:
            si.media.cross(np.flatnonzero(refracted & ok), entering, self.ior.take(mat))
        return BSDFSample(wi, value, pdf, flags.astype(np.int8))

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mat, eta, _, frame = self._local(si)
        wo_l, wi_l = to_local(si.wo, *frame), to_local(wi, *frame)
        f, pdf = self.lobe.eval(wo_l, wi_l, self._alpha(si, mat), eta, self.beckmann.take(mat),
                                self.separable.take(mat))
        matched = np.abs(eta - 1.0) < INDEX_MATCHED
        f_cos = si.color * np.where(matched & (wi_l[2] < 0.0), 0.0, f)
        scale = self._scale(si, mat, wo_l[2], eta)
        if scale is not None:
            f_cos = f_cos * scale
        return f_cos, np.where(matched & (wi_l[2] < 0.0), 0.0, pdf)

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        return self.eval(si, wi)[1]


class RoughGlass(RoughDielectric):
    """The ROUGH_GLASS row (engine/materials/table.py): glass materials with roughness > 0."""


class RoughRefraction(RoughDielectric):
    """Cycles' Refraction BSDF with roughness > 0: the refracted lobe alone, weight T = 1 (no
    Fresnel; total internal reflection ends the path, as Cycles' LABEL_NONE)."""
    reflection = False
    flags = REFRACTED | PASSED


class SmoothRefraction(BSDF):
    """Cycles' Refraction BSDF at roughness 0: delta refraction with the tint as weight, no reflected
    part; total internal reflection ends the path (weight 0)."""
    flags = PASSED

    def __init__(self, materials, settings):
        self.ior = np.array([max(m.ior, 1e-5) for m in materials], dtype=np.float64)

    def sample(self, si: ShadingPoint, u_lobe, u=None) -> BSDFSample:
        facing = specular_normal(si)
        eta_far, entering = refraction_eta(si, self.ior.take(si.material))
        eta = 1.0 / eta_far                                     # n1 / n2 (engine/materials/specular.py)
        cos_i = np.abs(dot(si.wo, facing))
        cos_t, tir = refract_cos(cos_i, eta)
        wi = refract(-si.wo, facing, cos_i, cos_t, eta)
        value = np.where(tir, 0.0, si.color)
        if si.media is not None:
            si.media.cross(np.flatnonzero(~tir), entering, self.ior.take(si.material))
        return BSDFSample(wi, value, np.where(tir, 0.0, 1.0), np.full(len(si), PASSED, dtype=np.int8))

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return delta_eval(si, wi)

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        return np.zeros(wi.shape[1])
