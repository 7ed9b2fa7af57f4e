"""Rough diffuse reflection as Blender's Cycles computes it (the Diffuse BSDF's Roughness socket).

Both models share Fujii's "improved Oren-Nayar" single-scatter lobe (FON; Y. Fujii,
"A tiny improvement of Oren-Nayar reflectance model"), for unit albedo

    f_ss = a + b s / t,   s = wi.wo - cos_i cos_o,   t = max(cos_i, cos_o) where s > 0, else 1,
    a = 1 / (pi + sigma (pi / 2 - 2 / 3)),   b = sigma a,   sigma = roughness clamped to [0, 1],

and f = rho f_ss for the albedo rho (Cycles' closure weight, the node's colour).  Its directional
albedo has a closed form (Fujii; Portsmouth, Kutz and Hill 2024, "EON: A practical
energy-preserving rough diffuse BRDF", eq. for E_FON):

    E(mu) = a pi + b G(mu),
    G(mu) = sin(th) (th - 2/3 - sin(th) mu) + 2/3 tan(th) (1 - sin(th)^3),   th = acos(mu),

and its cosine-weighted average E_avg = a pi + b (2 pi - 5.6) / 3 (the EON paper's
A (1 + (2/3 - 28 / (15 pi)) r)).

* `OrenNayar34`: Cycles 3.x (Blender 3.4's intern/cycles/kernel/closure/bsdf_oren_nayar.h): the
  single-scatter lobe alone, so a white surface reflects E(mu) < 1 (it loses energy: see
  docs/materials.md for the figures), sampled uniformly over the hemisphere (pdf 1 / (2 pi)).
* `EnergyPreservingOrenNayar`: Cycles 4.3+ (the same file in Blender 4.3, after
  "Switch to energy-preserving multiscattering Oren-Nayar BSDF"): the EON multiple-scatter lobe
  added, as Cycles writes it,

      f = rho [f_ss + E_ms (1 - E(cos_i)) (1 - E(cos_o))],
      E_ms = (1 / pi) rho_c^2 (E_avg / (1 - E_avg)) / (1 - rho_c (1 - E_avg)),  rho_c = clamp(rho, 0, 1),

  sampled by the cosine-weighted hemisphere as Cycles does (not OpenPBR's CLTC sampler).  A white
  surface (rho = 1) reflects exactly 1 at every incidence.  Note: Cycles multiplies the
  multiple-scatter lobe by the closure weight rho as well, so its multiple-scatter albedo is
  rho times the EON paper's rho_ms = rho^2 E_avg / (1 - rho (1 - E_avg)); the two agree for white.

Roughness 0: Cycles' Diffuse BSDF node sets up its Lambertian closure instead (kernel/svm/closure.h,
`roughness == 0.0f`), so the hits of such materials are scattered here exactly as
engine/materials/lambert.py scatters them (cosine sampling, f cos / pdf = rho bit for bit).

Directions and the cosines follow Cycles: cos_i, cos_o are clamped at 0 (a viewer below a smooth
shading normal sees the lobe of cos_o = 0), and the division by t adds FLT_MIN as Cycles does.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import dot
from ..sampling.warps import cosine_directions, to_world, unit_circle
from .protocol import BSDF, BSDFFlags, BSDFSample, ShadingPoint
from .textures import per_hit, textured_mask

LOBE = BSDFFlags.DIFFUSE | BSDFFlags.REFLECTION
FLT_MIN = 1.17549435e-38            # Cycles' guard of the division by t (float's smallest normal)
G_TAYLOR_BELOW = 1e-6               # Cycles: below this cosine, G by its Taylor expansion at 90 degrees


def fon_coefficients(sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(a, b) of the FON lobe for roughness sigma (clamped to [0, 1] as Cycles' saturatef)."""
    sigma = np.clip(sigma, 0.0, 1.0)
    a = 1.0 / (np.pi + sigma * (0.5 * np.pi - 2.0 / 3.0))
    return a, sigma * a


def fon_g(mu: np.ndarray) -> np.ndarray:
    """G(mu) of the FON directional albedo (Cycles' bsdf_oren_nayar_G), mu in [0, 1]."""
    mu = np.asarray(mu, dtype=np.float64)
    safe = np.maximum(mu, G_TAYLOR_BELOW)
    sin_t = np.sqrt(np.maximum(1.0 - safe * safe, 0.0))
    theta = np.arccos(np.clip(safe, -1.0, 1.0))
    g = sin_t * (theta - 2.0 / 3.0 - sin_t * safe) + (2.0 / 3.0) * (sin_t / safe) * (1.0 - sin_t * sin_t * sin_t)
    return np.where(mu < G_TAYLOR_BELOW, (0.5 * np.pi - 2.0 / 3.0) - mu, g)


def fon_albedo(mu: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """E(mu) = a pi + b G(mu): the directional albedo of the unit-albedo FON lobe."""
    return a * np.pi + b * fon_g(mu)


def fon_average_albedo(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """E_avg = 2 int_0^1 E(mu) mu dmu = a pi + b (2 pi - 5.6) / 3 (Cycles' Eavg)."""
    return a * np.pi + ((2.0 * np.pi - 5.6) / 3.0) * b


def _uniform_hemisphere(u1: np.ndarray, u2: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Directions uniform over the hemisphere of each normal, z = u1 as Cycles'
    sample_uniform_hemisphere (pdf 1 / (2 pi))."""
    z = np.asarray(u1, dtype=np.float64)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    c, s = unit_circle(u2)
    return to_world(np.stack([r * c, r * s, z]), normal)


class _FujiiOrenNayar(BSDF):
    """What both Cycles models share: per-material roughness, the FON lobe, Lambert at 0.

    roughness: one value per material id (a sequence); by default each material's `roughness`
    attribute (0, i.e. Lambertian, where it has none)."""
    flags = LOBE
    roughness_input = "diffuse_roughness"     # an image texture on it gives each hit its own (per_hit)

    def __init__(self, materials, settings, roughness=None):
        if roughness is None:
            roughness = [getattr(m, "roughness", 0.0) for m in materials]
        self.roughness = np.clip(np.asarray(roughness, dtype=np.float64).reshape(-1), 0.0, 1.0)

    # -- per hit ------------------------------------------------------------------------------------
    def _rough(self, si: ShadingPoint) -> tuple[np.ndarray, np.ndarray]:
        """(whether each hit's material is rough, its roughness; 1 where smooth, unused there)."""
        sigma = self.roughness.take(si.material) if len(self.roughness) else np.zeros(len(si))
        if len(self.roughness) and textured_mask(si, self.roughness_input) is not None:
            sigma = np.clip(per_hit(si, self.roughness, self.roughness_input), 0.0, 1.0)
        rough = sigma > 0.0
        return rough, np.where(rough, sigma, 1.0)

    def _f(self, si: ShadingPoint, wi: np.ndarray, cos_i: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """f (3, N) of the rough model (without the cosine) for cos_i = max(wi.n, 0)."""
        a, b = fon_coefficients(sigma)
        cos_o = np.maximum(dot(si.wo, si.n), 0.0)
        s = dot(wi, si.wo) - cos_i * cos_o
        s_over_t = np.where(s > 0.0, s / (np.maximum(cos_i, cos_o) + FLT_MIN), s)
        return si.color * (a + b * s_over_t) + self._multiple_scatter(si, cos_i, cos_o, a, b)

    def _multiple_scatter(self, si, cos_i, cos_o, a, b):
        return 0.0

    def _sample_rough(self, u, n):
        raise NotImplementedError

    def _pdf_rough(self, cos_i):
        raise NotImplementedError

    cosine_sampled = False          # the rough lobe samples (and has the pdf of) the cosine: as Lambert

    def _pdf(self, rough, cos):
        """pdf of directions with cos = wi.n: the rough lobe's where rough, Lambert's elsewhere."""
        lambert = np.maximum(cos, 0.0) * (1.0 / np.pi)
        if self.cosine_sampled or not rough.any():          # the same numbers as np.where(rough, ...)
            return lambert
        return np.where(rough, self._pdf_rough(cos), lambert)

    # -- the protocol -------------------------------------------------------------------------------
    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        rough, _ = self._rough(si)
        return self._pdf(rough, dot(wi, si.n))

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rough, sigma = self._rough(si)
        cos = dot(wi, si.n)
        pdf = self._pdf(rough, cos)
        cos_i = np.maximum(cos, 0.0)
        lambert = si.color * (cos_i * (1.0 / np.pi))
        if not rough.any():                                 # Lambert everywhere: np.where's numbers
            return lambert, pdf
        return np.where(rough, self._f(si, wi, cos_i, sigma) * cos_i, lambert), pdf

    def sample(self, si: ShadingPoint, u_lobe, u) -> BSDFSample:
        rough, sigma = self._rough(si)
        cosine = cosine_directions(u[0], u[1], si.n)
        if self.cosine_sampled or not rough.any():          # np.where(rough, ...) of equal directions
            wi = cosine
        else:
            wi = np.where(rough, self._sample_rough(u, si.n), cosine)
        cos = dot(wi, si.n)
        pdf = self._pdf(rough, cos)
        if not rough.any():                                 # Lambert: rho exactly (eq. 2.14)
            return BSDFSample(wi, si.color.copy(), pdf, np.full(len(si), LOBE, dtype=np.int8))
        cos_i = np.maximum(cos, 0.0)
        f_cos = self._f(si, wi, cos_i, sigma) * cos_i
        with np.errstate(divide="ignore", invalid="ignore"):
            weight = np.where(pdf > 0.0, f_cos / pdf, 0.0)
        value = np.where(rough, weight, si.color)              # Lambert: rho exactly (eq. 2.14)
        return BSDFSample(wi, value, pdf, np.full(len(si), LOBE, dtype=np.int8))


class OrenNayar34(_FujiiOrenNayar):
    """Cycles 3.x's Oren-Nayar (Blender 3.4): the FON single-scatter lobe, sampled uniformly."""

    def _sample_rough(self, u, n):
        return _uniform_hemisphere(u[0], u[1], n)

    def _pdf_rough(self, cos_i):
        return np.where(cos_i > 0.0, 0.5 / np.pi, 0.0)


class EnergyPreservingOrenNayar(_FujiiOrenNayar):
    """Cycles 4.3+'s energy-preserving Oren-Nayar (EON): FON plus the multiple-scatter lobe,
    sampled by the cosine-weighted hemisphere."""
    cosine_sampled = True

    def _sample_rough(self, u, n):
        return cosine_directions(u[0], u[1], n)

    def _pdf_rough(self, cos_i):
        return np.maximum(cos_i, 0.0) * (1.0 / np.pi)

    def _multiple_scatter(self, si, cos_i, cos_o, a, b):
        e_ms, loss_o = self._at_hits(si)
        loss = (1.0 - fon_albedo(cos_i, a, b)) * loss_o
        return si.color * e_ms * loss                         # times the closure weight, as Cycles

    def _at_hits(self, si: ShadingPoint):
        """(E_ms (3, N), 1 - E(cos_o) (N,)): the multiple-scatter terms of wo alone, once per hit for
        its sample and its evals (ShadingPoint.memo), from the roughness and cos_o that _f reads."""
        def terms(at):
            a, b = fon_coefficients(self._rough(at)[1])
            cos_o = np.maximum(dot(at.wo, at.n), 0.0)
            albedo = np.clip(at.color, 0.0, 1.0)
            e_avg = fon_average_albedo(a, b)
            e_ms = (1.0 / np.pi) * albedo * albedo * (e_avg / (1.0 - e_avg)) / (1.0 - albedo * (1.0 - e_avg))
            return e_ms, 1.0 - fon_albedo(cos_o, a, b)
        return si.memo((self, "multiple_scatter"), terms)


ENERGY_PRESERVING_SINCE = (4, 3)     # Cycles' switch to the EON model (Blender 4.3)


def rough_diffuse_model(cycles_version) -> type:
    """The Oren-Nayar of a Blender's Cycles: 3.x's below (4, 3), the energy-preserving one from it on."""
    return EnergyPreservingOrenNayar if tuple(cycles_version) >= ENERGY_PRESERVING_SINCE else OrenNayar34


class RoughDiffuse(BSDF):
    """The scatter row of the rough diffuse materials (engine/materials/table.py): the Oren-Nayar
    model of the scene's Cycles version with each material's `diffuse_roughness`."""
    flags = LOBE

    def __init__(self, materials, settings, cycles_version=(5, 0)):
        self.model = rough_diffuse_model(cycles_version)
        self.lobe = self.model(materials, settings, roughness=[getattr(m, "diffuse_roughness", 0.0)
                                                               for m in materials])

    def sample(self, si: ShadingPoint, u_lobe, u) -> BSDFSample:
        return self.lobe.sample(si, u_lobe, u)

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.lobe.eval(si, wi)

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        return self.lobe.pdf(si, wi)
