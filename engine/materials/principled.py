"""The Principled BSDF v2 (Blender 4.0+) as Cycles builds it from closures (its kernel/svm/closure.h,
case CLOSURE_BSDF_PRINCIPLED_ID; kernel/closure/bsdf_microfacet.h and bsdf_util.h; a public source:
blender/cycles src/kernel/), without subsurface and thin film.  Over the base (three lobes, in
Cycles' layering order: metallic, then specular over diffuse; with a Transmission Weight t the
glass closure of engine/materials/principled_glass.py between them, weight t (1 - metallic) W,
specular and diffuse then x (1 - t)) lie, from the top, alpha, the sheen and the coat ("The layers
over the base" below).  The base:

* metallic, weight `metallic`: GGX reflection with the F82-tint Fresnel, F0 = the base colour
  (clamped to 1) and the edge tint = the specular tint (clamped to 1);
* specular, weight (1 - metallic): GGX reflection with Cycles' generalized Schlick in its
  "real Fresnel" mode: F = mix(F0 x tint, 1, s(h)), s(h) = (F_d(wo.h, eta) - F0) / (1 - F0)
  clamped to [0, 1], F_d the dielectric Fresnel of eta; F0 = ((ior - 1) / (ior + 1))^2, and a
  specular IOR level other than 0.5 scales F0 by 2 x level and takes eta from that F0
  (ior_from_F0); eta = 1 (level 0) has no specular lobe;
* diffuse, weight (1 - metallic) x (1 - max_c A_spec,c(wo)) x base colour: Lambert, or the
  energy-preserving Oren-Nayar of engine/materials/oren_nayar.py where the diffuse roughness is
  at least 1e-5 (Cycles' diffuse_roughness_is_almost_zero).

Both microfacet lobes are those of engine/materials/glossy.py (alpha = roughness^2, anisotropy
clamped to [0, 1] stretching alpha_x / a and alpha_y x a, a = sqrt(1 - 0.9 anisotropy), along the
tangent turned by rotation; energy compensation where `multiscatter`, Cycles' "Multiscatter GGX",
the node's default).

The diffuse layer's weight follows Cycles' closure_layering_weight with bsdf_albedo: A_spec is not
the specular lobe's exact albedo but Cycles' estimate of it (bsdf_microfacet_estimate_albedo times
the darkening that microfacet_ggx_preserve_energy puts into the closure weight):

    A_spec(mu) = (E(mu) + F_ms (1 - E(mu))) x mix(F0 x tint, 1, s(mu))     (multiscatter; else the mix alone)

with E the GGX albedo table (engine/materials/albedo_tables.py) and s(mu) the mean of s(h) over
visible normals whose reflection leaves above the surface (Cycles' table ggx_gen_schlick_ior_s,
made by its app/cycles_precompute.cpp).  We compute s by our own Monte Carlo per material (its
roughness and eta exactly, at 32 points of mu, `mu_points`), where Cycles reads a 16^3 table over
roughness, mu and eta.  The estimate is not the lobe's albedo: at roughness >= 0.3 it exceeds it
(0.184 against 0.174 at mu = 0.1 for the default material), so a white Principled dielectric
reflects slightly less than 1 at grazing, as in Cycles; at low roughness and grazing it falls
below it and the white surface reflects up to 1 % more than it receives (roughness 0.1, mu = 0.05),
as Cycles' formula implies (docs/materials.md).

Sampling picks a lobe with probability proportional to Cycles' sample_weight (the closure weight's
average times the albedo estimate; for the metallic lobe Cycles estimates with the Schlick table,
exponent 5, ignoring the F82 bend) and returns the sum over lobes as value and pdf (one-sample MIS
over the closures, as Cycles' surface_shader_bsdf_eval_mis): eval and pdf are the sums of the
weighted lobes, so light samples and MIS see exactly the density that `sample` draws from.

The layers over the base (principled_bsdf_emission in closure.h), each darkening what lies below
it through closure_layering_weight, W <- W x clamp(1 - max_c(layer albedo / W), 0, 1), all at wo:

* alpha < 1: a straight pass-through of weight 1 - alpha (Cycles' Transparent BSDF), W = alpha.  We
  take it with probability exactly 1 - alpha (weight 1, flags TRANSMISSION | DELTA | STRAIGHT: the
  path goes on through the surface, direction and medium unchanged, its MIS state that of a delta
  bounce, a camera ray still a camera ray for the Area lights' visibility); the other
  lobes share the probability alpha.  Shadow rays do not pass alpha surfaces (they occlude as
  opaque ones): the light behind them is found by the pass-through rays alone, whose delta bounce
  counts the emission they reach fully (unbiased for lights that rays can hit; point, spot and
  sun lamps are fully shadowed: docs/materials.md).
* sheen, weight sheen_weight x sheen_tint x W: the microfiber sheen (engine/materials/sheen.py),
  albedo R(mu, sheen roughness) from its table; W <- W (1 - max_c(sheen_weight x tint_c x R)).
* coat, weight coat_weight x W: GGX reflection (alpha = coat roughness^2, isotropic) with the
  dielectric Fresnel of the coat IOR, energy-compensated always (bsdf_microfacet_setup_fresnel_
  dielectric calls microfacet_ggx_preserve_energy whatever the node's distribution);
  W <- W (1 - coat_weight x A_coat(mu)), A_coat = (E + F_ms (1 - E)) x mix(F0(coat IOR), 1, s(mu)) as
  A_spec; then the tint absorbs along the refracted path, W <- W x mix(1, tint^(1 / cos_t),
  coat_weight), cos_t = sqrt(1 - (1 - mu^2) / coat_ior^2).
* the base lobes' weights are multiplied by W (a colour once the coat is tinted).

Image textures on the roughness and metallic (engine/scene/model.py Material.input_textures) are read
per hit: the metallic weight, the lobes' alphas (`principled_alpha_rows`), and s(mu) at the hit's
roughness, linear between our s tables at ROUGHNESS_POINTS roughnesses r = i / 15 (Cycles' table has
16 roughness points, read linearly too; `_textured_s`); untextured hits keep the material's own.

Emission is not a lobe: Material.emission (the exporter multiplies it by alpha, as Cycles; the coat
and sheen's darkening of it is not modelled).  Materials without any of these layers run the base
alone (the same arithmetic as before the layers existed: their images are bit-identical).
"""
from __future__ import annotations

import sys
from functools import lru_cache
from types import SimpleNamespace

import numpy as np

from ..core import table_cache, vec
from ..core.backend import JIT_MODULES, NUMBA
from ..core.vec import dot
from ..sampling import warps
from ..scene.model import PRINCIPLED, Principled, PrincipledV1
from . import albedo_tables, glossy, microfacet
from .glossy import MicrofacetReflection, fresnel_dielectric, fresnel_dielectric_average
from .microfacet import GGX, clamp_alpha, ggx_sample_vndf
from .oren_nayar import EnergyPreservingOrenNayar
from .principled_glass import FLAGS as GLASS_LOBES, PrincipledGlass
from .protocol import BSDF, BSDFFlags, BSDFSample, ShadingPoint
from .sheen import LOBE as SHEEN_LOBE, MicrofiberSheen
from .specular import specular_normal_at
from .textures import per_hit, textured_mask

FLAGS = BSDFFlags.REFLECTION | BSDFFlags.DIFFUSE | BSDFFlags.GLOSSY
PASS_LOBE = BSDFFlags.TRANSMISSION | BSDFFlags.DELTA | BSDFFlags.STRAIGHT      # alpha's pass-through
WEIGHT_CUTOFF = 1e-5                # Cycles' CLOSURE_WEIGHT_CUTOFF: lobes below it are not set up
DIFFUSE_ROUGHNESS_CUTOFF = 1e-5     # Cycles' diffuse_roughness_is_almost_zero
MU_POINTS = 32                      # points of mu of our s(mu) tables, squared spacing (see mu_points)
ESTIMATE_STRATA = 64                # our Monte Carlo of s(mu): 64 x 64 jittered samples per point
ROUGHNESS_POINTS = 16               # s(mu) tables over roughness for textured roughness (i / 15)


def f0_from_ior(ior):
    """Normal-incidence reflectance ((ior - 1) / (ior + 1))^2 (Cycles' F0_from_ior)."""
    return ((np.asarray(ior, dtype=np.float64) - 1.0) / (np.asarray(ior, dtype=np.float64) + 1.0)) ** 2


def ior_from_f0(f0):
    """The IOR whose F0 is f0, f0 clamped to [0, 0.99] (Cycles' ior_from_F0)."""
    r = np.sqrt(np.clip(f0, 0.0, 0.99))
    return (1.0 + r) / (1.0 - r)


def specular_eta_f0(ior: float, specular_ior_level: float) -> tuple[float, float]:
    """(eta, F0) of the specular layer: the IOR's, or F0 x 2 level and its IOR (closure.h,
    "Apply IOR adjustment")."""
    eta = float(ior)
    f0 = float(f0_from_ior(eta))
    if specular_ior_level != 0.5:
        f0 *= 2.0 * specular_ior_level
        eta = float(ior_from_f0(f0))
        if ior < 1.0:
            eta = 1.0 / eta
    return eta, f0


def real_fresnel_s(cos: np.ndarray, eta) -> np.ndarray:
    """s = (F_d(cos, eta) - F0) / (1 - F0) clamped to [0, 1]: where the dielectric Fresnel is
    between its F0 and 1 (generalized_schlick_fresnel with a negative exponent)."""
    f0 = f0_from_ior(eta)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (fresnel_dielectric(cos, eta) - f0) / (1.0 - f0)
    return np.clip(np.nan_to_num(s, nan=1.0), 0.0, 1.0)


def mu_points() -> np.ndarray:
    """The points of mu of the s(mu) tables: (j / 31)^2 clamped to at least 1e-4, read linearly in
    sqrt(mu).  Cycles' tables have 16 points j / 15 read linearly in mu; near grazing that misses
    the steep s(mu) of low roughness by up to 0.03 (a white surface of roughness 0.1 reflected
    1.036 at mu = 0.03 with that grid); ours follows Cycles' formula to 0.002."""
    return np.clip((np.arange(MU_POINTS) / (MU_POINTS - 1)) ** 2, 1e-4, 1.0)


@lru_cache(maxsize=256)
def interpolation_factor(roughness: float, eta: float | None) -> np.ndarray:
    """s at mu_points() (MU_POINTS,): the mean over GGX visible normals (alpha = roughness^2) of the
    Fresnel's interpolation factor s(h), 0 where the reflection leaves below the surface (as
    Cycles' precompute_ggx_gen_schlick_s).  eta: the real-Fresnel factor of that IOR; None: the
    Schlick factor (1 - wo.h)^5 (Cycles' ggx_gen_schlick_s at exponent 5).  Each table costs 10-30
    ms, paid by every worker at its start for every material: read from the per-user cache of
    tables where an earlier process computed it with this code (engine/core/table_cache.py)."""
    inputs = (float(roughness), None if eta is None else float(eta), MU_POINTS, ESTIMATE_STRATA)
    return table_cache.cached("principled_s", _s_table_sources(), inputs,
                              lambda: estimate_interpolation_factor(roughness, eta))


def _s_table_sources() -> tuple:
    """The source files of the code estimate_interpolation_factor runs (its cache key)."""
    return tuple(module.__file__ for module in (sys.modules[__name__], glossy, microfacet, vec, warps))


def estimate_interpolation_factor(roughness: float, eta: float | None) -> np.ndarray:
    """interpolation_factor computed: our Monte Carlo of 64 x 64 jittered samples per point."""
    alpha = max(roughness * roughness, 1e-8)
    rng = np.random.default_rng(20240)
    i = np.arange(ESTIMATE_STRATA * ESTIMATE_STRATA)
    u1 = (i // ESTIMATE_STRATA + rng.random(i.size)) / ESTIMATE_STRATA
    u2 = (i % ESTIMATE_STRATA + rng.random(i.size)) / ESTIMATE_STRATA
    out = np.empty(MU_POINTS)
    for j, mu in enumerate(mu_points()):
        wo = np.stack([np.full(i.size, np.sqrt(1.0 - mu * mu)), np.zeros(i.size), np.full(i.size, mu)])
        h = ggx_sample_vndf(wo, alpha, alpha, u1, u2)
        cos = np.clip((wo * h).sum(axis=0), 0.0, 1.0)
        above = (2.0 * cos * h[2] - wo[2]) > 0.0
        s = (1.0 - cos) ** 5 if eta is None else real_fresnel_s(cos, np.full(i.size, eta))
        out[j] = np.where(above, s, 0.0).mean()
    return np.clip(out, 0.0, 1.0)


def _sample_lobes(lobes, views, choice, first, u, wi, flags, failed=None):
    """Each lobe's directions for the hits that picked it (choice == first + its place in `lobes`),
    written into wi and flags; failed (when given): where the lobe's sample failed (a failed
    sample may point through the surface)."""
    for code, (lobe, view) in enumerate(zip(lobes, views), start=first):
        idx = np.flatnonzero(choice == code)
        if not len(idx):
            continue
        s = lobe.sample(view.take(idx), None, (u[0].take(idx), u[1].take(idx)))
        wi[:, idx] = s.wi
        flags[idx] = s.flags
        if failed is not None:
            failed[idx] = s.pdf <= 0.0

class _SpecularLayer(MicrofacetReflection):
    """The Principled BSDF's dielectric specular lobe: F = mix(F0 x tint, 1, s(h)) (hits' colour =
    F0 x tint clamped to 1, set by PrincipledV2), at the per-material eta in `self.ior`."""

    def _fresnel(self, si: ShadingPoint, cos: np.ndarray) -> np.ndarray:
        s = real_fresnel_s(cos, self.ior.take(si.material))
        return si.color + (1.0 - si.color) * s

    def _fresnel_average(self, si: ShadingPoint) -> np.ndarray:
        eta = self.ior.take(si.material)
        f0 = f0_from_ior(eta)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.clip(np.nan_to_num((fresnel_dielectric_average(eta) - f0) / (1.0 - f0), nan=1.0), 0.0, 1.0)
        return si.color + (1.0 - si.color) * s


def _lobe_material(m, fresnel: str, ior: float, edge_tint) -> SimpleNamespace:
    """The microfacet lobe's view of Principled material m (the fields glossy.py reads)."""
    return SimpleNamespace(roughness=m.roughness, anisotropy=min(max(m.anisotropy, 0.0), 1.0), rotation=m.rotation,
                           tangent=m.tangent, distribution=GGX, fresnel=fresnel, ior=ior,
                           multiscatter=bool(m.multiscatter), edge_tint=edge_tint)


def principled_alphas(roughness: float, anisotropy: float) -> tuple[float, float]:
    """(alpha_x, alpha_y) of the Principled node (closure.h): alpha = roughness^2, anisotropy a
    clamped to [0, 1]: aspect = sqrt(1 - 0.9 a), alpha_x = alpha / aspect, alpha_y = alpha x aspect;
    each floored as the Glossy node's (engine/materials/microfacet.py clamp_alpha): roughness 0 is
    the narrowest lobe, never alpha 0 (a pdf of 0 would make a polished metal black)."""
    alpha = min(max(roughness, 0.0), 1.0) ** 2
    a = min(max(anisotropy, 0.0), 1.0)
    if a <= 0.0:
        return float(clamp_alpha(alpha)), float(clamp_alpha(alpha))
    aspect = np.sqrt(1.0 - 0.9 * a)
    return float(clamp_alpha(alpha / aspect)), float(clamp_alpha(alpha * aspect))


def principled_alpha_rows(roughness: np.ndarray, anisotropy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """principled_alphas over arrays (N,) (textured roughness)."""
    alpha = np.clip(roughness, 0.0, 1.0) ** 2
    aspect = np.sqrt(1.0 - 0.9 * np.clip(anisotropy, 0.0, 1.0))
    return clamp_alpha(alpha / aspect), clamp_alpha(alpha * aspect)


class PrincipledV2(BSDF):
    """The Principled BSDF v2 of every material (engine/scene/model.py Principled): metallic,
    specular and diffuse lobes, weighted and sampled as Cycles does (see the module)."""
    flags = FLAGS
    compiled = None                     # engine/materials/principled_jit.py when the backend is numba

    def __init__(self, materials, settings):
        params = [p if isinstance(p := getattr(m, "principled", None), Principled) else None for m in materials]
        m_count = len(materials)
        self.metallic = np.array([0.0 if p is None else min(max(p.metallic, 0.0), 1.0) for p in params])
        tint = np.array([(1.0, 1.0, 1.0) if p is None else np.maximum(p.specular_tint, 0.0) for p in params],
                        dtype=np.float64).reshape(m_count, 3)
        eta_f0 = [specular_eta_f0(max(m.ior, 1e-5), 0.5 if p is None else max(p.specular_ior_level, 0.0))
                  for m, p in zip(materials, params)]
        self.eta = np.array([e for e, _ in eta_f0], dtype=np.float64).reshape(m_count)
        self.has_specular = self.eta != 1.0
        self.spec_f0 = np.clip(np.array([f for _, f in eta_f0]).reshape(m_count, 1) * tint, 0.0, 1.0).T.copy()
        self.metal = MicrofacetReflection([_lobe_material(m, "f82", 1.0, tuple(np.minimum(t, 1.0)))
                                           for m, t in zip(materials, tint)], settings)
        self.metal_tint = np.ascontiguousarray(np.clip(self.metal.edge_tint, 0.0, 1.0))  # its F82 b's (3, M)
        self.specular = _SpecularLayer([_lobe_material(m, "dielectric", e, (1.0, 1.0, 1.0))
                                        for m, (e, _) in zip(materials, eta_f0)], settings)
        alphas = np.array([principled_alphas(m.roughness, m.anisotropy) for m in materials]).reshape(m_count, 2)
        for lobe in (self.metal, self.specular):
            lobe.ax, lobe.ay = alphas[:, 0].copy(), alphas[:, 1].copy()
            lobe.roughness_of_table = np.sqrt(np.sqrt(lobe.ax * lobe.ay))
            lobe.alpha_rule = principled_alpha_rows
        self._s_grids = {}                  # textured roughness: material -> s tables over roughness
        # Cycles' s(mu) tables, for the Principled materials only (every row of the material
        # table is built for all materials, engine/materials/table.py).
        rough = self.specular.roughness_of_table
        own = [getattr(m, "kind", PRINCIPLED) == PRINCIPLED and not isinstance(getattr(m, "principled", None), PrincipledV1)
               for m in materials]
        none = np.zeros(MU_POINTS)
        self.s_specular = np.array([interpolation_factor(float(r), float(e)) if mine and e != 1.0 else none
                                    for r, e, mine in zip(rough, self.eta, own)]).reshape(m_count, MU_POINTS)
        self.s_metal = np.array([interpolation_factor(float(r), None) if mine else none
                                 for r, mine in zip(rough, own)]).reshape(m_count, MU_POINTS)
        diffuse_roughness = [getattr(m, "diffuse_roughness", 0.0) for m in materials]
        self.diffuse = EnergyPreservingOrenNayar(
            materials, settings, roughness=[r if r >= DIFFUSE_ROUGHNESS_CUTOFF else 0.0 for r in diffuse_roughness])
        self._init_layers(materials, params, own, settings)

    def _init_layers(self, materials, params, own, settings):
        """The coat, sheen and alpha of each material (zero where a material has none)."""
        m_count = len(materials)
        layers = [p if (p is not None and mine and (p.layered or p.transmission_weight > 0.0)) else None
                  for p, mine in zip(params, own)]
        self.layered = np.array([p is not None for p in layers], dtype=bool)
        self.any_layers = bool(self.layered.any())
        self.any_transmission = False
        if not self.any_layers:
            return

        def per(name, default):
            return np.array([default if p is None else getattr(p, name) for p in layers], dtype=np.float64)

        def colour(name):
            return np.array([(1.0, 1.0, 1.0) if p is None else np.maximum(getattr(p, name), 0.0) for p in layers],
                            dtype=np.float64).reshape(m_count, 3).T.copy()
        self.alpha = np.clip(per("alpha", 1.0), 0.0, 1.0)
        self.sheen_weight = np.maximum(per("sheen_weight", 0.0), 0.0)
        self.sheen_weight = np.where(self.sheen_weight > WEIGHT_CUTOFF, self.sheen_weight, 0.0)
        self.sheen_roughness = np.clip(per("sheen_roughness", 0.5), 0.0, 1.0)
        self.sheen_tint = colour("sheen_tint")
        self.coat_weight = np.maximum(per("coat_weight", 0.0), 0.0)
        self.coat_weight = np.where(self.coat_weight > WEIGHT_CUTOFF, self.coat_weight, 0.0)
        self.coat_ior = np.maximum(per("coat_ior", 1.5), 1.0)
        self.coat_tint = colour("coat_tint")
        self.coat_tinted = np.any(self.coat_tint != 1.0, axis=0) & (self.coat_weight > 0.0)
        coat_rough = np.clip(per("coat_roughness", 0.03), 0.0, 1.0)
        self.coat = MicrofacetReflection([SimpleNamespace(roughness=r, anisotropy=0.0, rotation=0.0, tangent=(1.0, 0.0, 0.0),
                                                          distribution=GGX, fresnel="dielectric", ior=e, multiscatter=True)
                                          for r, e in zip(coat_rough, self.coat_ior)], settings)
        alphas = np.array([principled_alphas(r, 0.0) for r in coat_rough]).reshape(m_count, 2)
        self.coat.roughness_input = None            # the coat's own roughness: no texture
        self.coat.ax, self.coat.ay = alphas[:, 0].copy(), alphas[:, 1].copy()
        self.coat.roughness_of_table = np.sqrt(np.sqrt(self.coat.ax * self.coat.ay))
        none = np.zeros(MU_POINTS)
        self.s_coat = np.array([interpolation_factor(float(r), float(e)) if w > 0.0 else none
                                for r, e, w in zip(self.coat.roughness_of_table, self.coat_ior, self.coat_weight)]
                               ).reshape(m_count, MU_POINTS)
        self.sheen = MicrofiberSheen()
        if np.any(self.alpha < 1.0):
            self.flags = FLAGS | PASS_LOBE
        # The transmission closure (engine/materials/principled_glass.py): light from the far side too.
        self.glass = PrincipledGlass(materials, per("transmission_weight", 0.0),
                                     np.array([(1.0, 1.0, 1.0) if p is None else np.maximum(p.specular_tint, 0.0)
                                               for p in layers], dtype=np.float64).reshape(m_count, 3).T)
        self.any_transmission = bool(np.any(self.glass.transmission > 0.0))
        if self.any_transmission:
            self.flags = self.flags | GLASS_LOBES

    def use_backend(self, backends: dict) -> None:
        """The eval (the base and the sheen and coat over it) and the base's sample compiled
        (engine/materials/principled_jit.py, the same numbers) when the render runs the Principled
        effects on numba and no material has a rough diffuse (that keeps the NumPy lobes).  The
        transmission closure's setup stays NumPy's (principled_glass.py), added after the compiled
        lobes as _layered_mixture adds it last (`_add_glass`); its GGX lobe with the coloured Fresnel
        is compiled too (engine/materials/dielectric_jit.py `sample_coloured`, `eval_coloured`),
        rough diffuse or not."""
        super().use_backend(backends)
        on_numba = any(backends.get(k) == NUMBA for k in JIT_MODULES["materials.principled_jit"])
        fusable = not bool((self.diffuse.roughness > 0.0).any())
        if fusable and on_numba:
            from . import principled_jit
            self.compiled = principled_jit
        else:
            self.compiled = None
        if self.any_transmission:                   # its GGX glass lobe with the coloured Fresnel
            if on_numba:
                from . import dielectric_jit
                self.glass.lobe.compiled = dielectric_jit
            else:
                self.glass.lobe.compiled = None

    def _fused_hits(self, si: ShadingPoint):
        """What the compiled base reads per hit (C-contiguous, over the hits on the last axis): wo;
        the microfacet frame x, y, n and alphas ax, ay the metallic and specular lobes share (both
        are set up from the material's roughness, anisotropy, tangent and rotation); the material
        ids mat and the metal's F0 (the kernel makes its F82 b from F0 and `metal_tint`), the specular
        colour, eta and F0; both compensations (None where none); the diffuse normal nd and colour;
        the lobe weights and probabilities; over_base: a sheen or a coat at some hit; where any material transmits,
        `glass`: the transmission closure's weight w (3, N), probability p (N,) and where it is set
        up, on (N,) (its lobe is NumPy's, `_add_glass`).  None where a diffuse roughness texture may
        make the diffuse lobe rough (the NumPy lobes then)."""
        if textured_mask(si, self.diffuse.roughness_input) is not None:
            return None
        metal, specular, _ = self._views(si)
        n_hits = len(si)
        layers = None
        if self.any_layers:
            layers, weights, prob = self._lobes_at(si)
            w_metal, w_spec, w_diffuse = weights[2:5]
        else:
            (w_metal, w_spec, w_diffuse), prob = self._lobes_at(si)
            w_metal, w_spec, w_diffuse = (np.broadcast_to(w, (3, n_hits)) for w in (w_metal, w_spec, w_diffuse))
        x, y, n = self.metal._frame_at(metal)
        ax, ay, _ = self.metal._alphas(metal)

        def compensation(lobe, view):
            scale = lobe.compensation_at(view)
            return None if scale is None else np.ascontiguousarray(scale)
        f0_metal = np.clip(metal.color, 0.0, 1.0)
        eta = self.specular.ior.take(si.material)
        rows = np.ascontiguousarray
        on_metal, on_spec, on_diffuse = (w.max(axis=0) > 0.0 for w in (w_metal, w_spec, w_diffuse))
        hits = SimpleNamespace(
            wo=rows(si.wo), x=rows(x), y=rows(y), n=rows(n), ax=rows(ax), ay=rows(ay),
            mat=rows(si.material, dtype=np.int64), f0_metal=rows(f0_metal),
            comp_metal=compensation(self.metal, metal), spec_colour=rows(specular.color), eta=rows(eta),
            f0_spec=rows(f0_from_ior(eta)), comp_spec=compensation(self.specular, specular),
            nd=rows(si.n), colour=rows(si.color), w_metal=rows(w_metal), w_spec=rows(w_spec),
            w_diffuse=rows(w_diffuse), on_metal=on_metal, on_spec=on_spec, on_diffuse=on_diffuse, prob=rows(prob),
            base_row=0, any_metal=bool(on_metal.any()), layered=layers is not None, over_base=False, glass=None)
        if self.any_transmission:
            hits.glass = SimpleNamespace(w=weights[5], p=prob[6], on=weights[5].max(axis=0) > 0.0,
                                         setup=self._glass_setup(si))
        if layers is not None:
            hits.base_row = 3
            if layers.bare:                 # no sheen nor coat at these hits: their weights are zeros
                coat_on = sheen_on = np.zeros(n_hits, dtype=bool)
            else:
                coat_on, sheen_on = weights[1].max(axis=0) > 0.0, weights[0].max(axis=0) > 0.0
            hits.over_base = bool(coat_on.any() or sheen_on.any())
            if coat_on.any():
                coat_view = layers.coat_view
                cx, cy, cn = self.coat._frame_at(coat_view)
                cax, cay, _ = self.coat._alphas(coat_view)
                comp_coat = compensation(self.coat, coat_view)
                coat_eta = self.coat.ior.take(si.material)
            else:                   # no coat here: the kernels read none of its values (only where on)
                cx, cy, cn, cax, cay, comp_coat, coat_eta = hits.x, hits.y, hits.n, hits.ax, hits.ay, None, hits.eta
            sx, sy = self.sheen.frame(si) if sheen_on.any() else (hits.x, hits.y)
            hits.coat = SimpleNamespace(x=rows(cx), y=rows(cy), n=rows(cn), ax=rows(cax), ay=rows(cay),
                                        w=rows(weights[1]), on=coat_on, eta=rows(coat_eta), comp=comp_coat)
            hits.sheen = SimpleNamespace(x=rows(sx), y=rows(sy), n=rows(si.n), a=rows(layers.sheen_a),
                                         b=rows(layers.sheen_b), w=rows(weights[0]), on=sheen_on)
        return hits

    # -- the layers at the hits ---------------------------------------------------------------
    def _views(self, si: ShadingPoint):
        """The ShadingPoints the three lobes see: the colour is F0 of the metal (the clamped base
        colour), F0 x tint of the specular layer, the base colour of the diffuse.  The two
        microfacet lobes build their frames on Cycles' valid-reflection normal themselves
        (engine/materials/glossy.py, engine/materials/specular.py specular_normal_at); the diffuse
        lobe keeps the shading normal."""
        def views(at):
            return (at.recolour(np.minimum(at.color, 1.0)), at.recolour(self.spec_f0.take(at.material, axis=1)))
        metal, specular = si.memo((self, "views"), views)
        return metal, specular, si

    def _darkening(self, lobe: MicrofacetReflection, si: ShadingPoint, cos_o: np.ndarray,
                   at_lobe_normal: bool = False) -> np.ndarray:
        """E + F_ms (1 - E) (3, N): what microfacet_ggx_preserve_energy multiplies the closure
        weight by (its compensation times E); 1 where the material does not compensate.
        at_lobe_normal: cos_o is the lobe's own (dot(wo, specular_normal_at)), whose E its
        compensation has read already."""
        scale = lobe.compensation_at(si)            # cos_o is clip(dot(wo, n)): compensation clips
        if scale is None:
            return np.ones((3, len(si)))
        e = (lobe.albedo_at(si) if at_lobe_normal
             else albedo_tables.albedo(lobe.table_roughness(si), np.clip(cos_o, 0.0, 1.0)))
        return np.where(lobe.compensate.take(si.material), scale * e, 1.0)

    def _textured_s(self, si: ShadingPoint, mu: np.ndarray, s_metal: np.ndarray, s_spec: np.ndarray):
        """s_metal, s_spec (N,) with the hits of textured roughness read at their roughness: linear
        between the s tables at ROUGHNESS_POINTS roughnesses (made once per material)."""
        textured = textured_mask(si, self.specular.roughness_input)
        if textured is None:
            return s_metal, s_spec
        idx = np.flatnonzero(textured)
        x = np.clip(self.specular.table_roughness(si.take(idx)), 0.0, 1.0) * (ROUGHNESS_POINTS - 1)
        i = np.minimum(x.astype(np.int64), ROUGHNESS_POINTS - 2)
        t = x - i
        rows = si.material.take(idx)
        s_metal, s_spec = s_metal.copy(), s_spec.copy()
        for m in np.unique(rows):
            if int(m) not in self._s_grids:
                eta = float(self.eta[m])
                grid = np.arange(ROUGHNESS_POINTS) / (ROUGHNESS_POINTS - 1)
                self._s_grids[int(m)] = (np.array([interpolation_factor(float(r), None) for r in grid]),
                                         np.array([interpolation_factor(float(r), eta) if eta != 1.0
                                                   else np.zeros(MU_POINTS) for r in grid]))
            metal_grid, spec_grid = self._s_grids[int(m)]
            mine = np.flatnonzero(rows == m)
            at, ti, mu_m = i.take(mine), t.take(mine), mu.take(idx.take(mine))
            for grid, out in ((metal_grid, s_metal), (spec_grid, s_spec)):
                low, high = _read(grid, at, mu_m), _read(grid, at + 1, mu_m)
                out[idx.take(mine)] = (1.0 - ti) * low + ti * high
        return s_metal, s_spec

    def _s_at(self, si: ShadingPoint, mu: np.ndarray):
        """(s_metal, s_spec) (N,) at the hits' mu: the material's tables, read at the hit's roughness
        where it is textured (`_textured_s`)."""
        return self._textured_s(si, mu, *_read_both(self.s_metal, self.s_specular, si.material, mu))

    def layer_albedos(self, si: ShadingPoint):
        """Cycles' albedo estimates (3, N) of the metallic and the specular lobe at wo (without
        their weights): darkening x mix(F0, 1, s(mu)) (bsdf_albedo)."""
        metal, specular, _ = self._views(si)
        mu = np.clip(dot(si.wo, specular_normal_at(si)), 0.0, 1.0)   # the lobes' normal (bsdf_albedo)
        rows = si.material
        textured = textured_mask(si, self.specular.roughness_input) is not None
        if not textured and not self.has_specular.any():     # no specular lobe: a_spec is np.where's 0 everywhere
            s_metal = _read(self.s_metal, rows, mu)
            a_metal = self._darkening(self.metal, metal, mu, True) * (metal.color + (1.0 - metal.color) * s_metal)
            return a_metal, np.zeros((3, len(si)))
        s_metal, s_spec = self._s_at(si, mu)
        a_metal = self._darkening(self.metal, metal, mu, True) * (metal.color + (1.0 - metal.color) * s_metal)
        a_spec = self._darkening(self.specular, specular, mu, True) * (specular.color + (1.0 - specular.color) * s_spec)
        return a_metal, np.where(self.has_specular.take(rows), a_spec, 0.0)

    def lobe_weights(self, si: ShadingPoint, sample_total: bool = False):
        """((w_metal, w_specular, w_diffuse) (N,) each: the lobes' scalar closure weights, and
        their sampling probabilities (3, N)), as closure.h and the closures' sample_weight
        (sample_total: the sample weights themselves, unnormalised).  Compiled in one pass
        (principled_jit.py lobe_weights, the same numbers) on the numba backend."""
        if self.compiled is not None:
            return self.compiled.lobe_weights(self._compiled_lobe_inputs(si), not sample_total)
        rows = si.material
        m = np.clip(per_hit(si, self.metallic, "metallic"), 0.0, 1.0)
        w_metal = np.where(m > WEIGHT_CUTOFF, m, 0.0)
        w_rest = 1.0 - m
        w_rest = np.where(w_rest > WEIGHT_CUTOFF, w_rest, 0.0)
        if self.any_transmission:                   # the glass closure takes t of the dielectric base
            w_rest = w_rest * (1.0 - self.glass.transmission.take(rows))
        a_metal, a_spec = self.layer_albedos(si)
        w_spec = np.where(self.has_specular.take(rows), w_rest, 0.0)
        w_diffuse = w_rest * np.clip(1.0 - a_spec.max(axis=0), 0.0, 1.0)
        if si.glossy_off is not None:       # Reflective Caustics off (engine/integrators/light_paths.py)
            w_metal, w_spec = np.where(si.glossy_off, 0.0, w_metal), np.where(si.glossy_off, 0.0, w_spec)
            w_diffuse = np.where(si.glossy_off, w_rest, w_diffuse)       # not darkened by a left-out layer
        sample = np.stack([w_metal * a_metal.mean(axis=0), w_spec * a_spec.mean(axis=0),
                           w_diffuse * np.abs(si.color).mean(axis=0)])
        if sample_total:
            return (w_metal, w_spec, w_diffuse), sample
        total = sample.sum(axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            prob = np.where(total > 0.0, sample / total, 0.0)
        return (w_metal, w_spec, w_diffuse), prob

    def _compiled_lobe_inputs(self, si: ShadingPoint) -> SimpleNamespace:
        """What principled_jit.py's lobe_weights and layered_lobes read per hit: NumPy's inputs of
        lobe_weights (the metallic, the lobes' colours and darkening, each only where lobe_weights reads
        it; s(mu) at textured roughness, `_textured_s`) and the material tables."""
        metal, specular, _ = self._views(si)
        s_hits = None
        if textured_mask(si, self.specular.roughness_input) is not None:
            s_hits = np.stack(self._s_at(si, np.clip(dot(si.wo, specular_normal_at(si)), 0.0, 1.0)))
        any_specular = bool(self.has_specular.any())
        dark = [None if not on or lobe.compensation_at(view) is None else self._darkening(lobe, view, None, True)
                for lobe, view, on in ((self.metal, metal, True), (self.specular, specular, any_specular))]
        return SimpleNamespace(
            mat=si.material, metallic=per_hit(si, self.metallic, "metallic"), wo=si.wo, ns=specular_normal_at(si),
            s_metal=self.s_metal, s_spec=self.s_specular, s_hits=s_hits, metal_colour=metal.color,
            spec_colour=specular.color, dark_metal=dark[0], dark_spec=dark[1], has_specular=self.has_specular,
            transmission=self.glass.transmission if self.any_transmission else None, colour=si.color,
            glossy_off=si.glossy_off, cutoff=WEIGHT_CUTOFF)

    def _mixture(self, si: ShadingPoint, wi: np.ndarray, weights, prob):
        """(f cos (3, N), pdf (N,)): the weighted lobes summed, each evaluated where it is set up."""
        f_cos, pdf = np.zeros((3, len(si))), np.zeros(len(si))
        for lobe, view, w, p in zip((self.metal, self.specular, self.diffuse), self._views(si), weights, prob):
            idx = np.flatnonzero(w > 0.0)
            if not len(idx):
                continue
            if len(idx) == len(si):                 # every hit: no gathers, the same numbers
                f_l, pdf_l = lobe.eval(view, wi)
                f_cos += w * f_l
                pdf += p * pdf_l
                continue
            f_l, pdf_l = lobe.eval(view.take(idx), wi.take(idx, axis=1))
            f_cos[:, idx] += w.take(idx) * f_l
            pdf[idx] += p.take(idx) * pdf_l
        return f_cos, pdf

    # -- the layers over the base ---------------------------------------------------------------
    def layer_weights(self, si: ShadingPoint):
        """The layers at the hits (see the module): a namespace of the pass-through weight (N,),
        the sheen's closure weight (3, N) and LTC (a, b), the coat's closure weight (3, N), the
        base's weight W (3, N), the albedo estimates sheen_albedo (N,) and coat_albedo (N,), alpha (N,),
        and `bare`: no sheen nor coat at these hits (their weights and albedos are zeros that no one
        writes, W is alpha in every channel: read-only views and untouched zeros, not filled arrays)."""
        rows = si.material
        n = len(si)
        alpha = self.alpha.take(rows)
        sheen_w = self.sheen_weight.take(rows)
        coat_w = self.coat_weight.take(rows)
        if not (sheen_w.any() or coat_w.any()):
            # neither layer at these hits: the lines below give this (0 x finite = +0, w x clip(1 - 0) = w,
            # no tint without a coat weight); base is a read-only view of alpha
            return SimpleNamespace(
                through=1.0 - alpha, sheen=np.zeros((3, n)), sheen_a=np.zeros(n), sheen_b=np.zeros(n),
                coat=np.zeros((3, n)), base=np.broadcast_to(alpha, (3, n)), sheen_albedo=np.zeros(n),
                coat_albedo=np.zeros(n), coat_view=si.recolour(np.broadcast_to(1.0, (3, n))), alpha=alpha, bare=True)
        w = np.tile(alpha, (3, 1))
        mu = np.clip(dot(si.wo, si.n), 0.0, 1.0)
        a, b, r = self._sheen_params(si, sheen_w)
        r = np.where(sheen_w > 0.0, r, 0.0)
        sheen = sheen_w * self.sheen_tint.take(rows, axis=1) * r * w
        w = w * np.clip(1.0 - (sheen_w * self.sheen_tint.take(rows, axis=1) * r).max(axis=0), 0.0, 1.0)
        # Reflective Caustics off (engine/integrators/light_paths.py): no coat closure, nor its
        # darkening of the base; its tint stays (closure.h)
        coat_on = coat_w if si.glossy_off is None else np.where(si.glossy_off, 0.0, coat_w)
        coat = coat_on * w
        coat_view = si.recolour(np.ones((3, n)))
        ior = self.coat_ior.take(rows)
        if np.any(coat_on > 0.0):
            f0 = f0_from_ior(ior)
            s_coat = _read(self.s_coat, rows, mu)
            a_coat = self._darkening(self.coat, coat_view, mu)[0] * (f0 + (1.0 - f0) * s_coat)
            a_coat = np.where(coat_on > 0.0, a_coat, 0.0)
            w = w * np.clip(1.0 - coat_on * a_coat, 0.0, 1.0)
        else:                                       # no coat here: a_coat 0, w x clip(1 - 0 x 0) = w
            a_coat = np.zeros(n)
        tinted = self.coat_tinted.take(rows)
        if tinted.any():
            cos_t = np.sqrt(np.maximum(1.0 - (1.0 - mu * mu) / (ior * ior), 0.0))
            with np.errstate(divide="ignore"):
                absorbed = self.coat_tint.take(rows, axis=1) ** (1.0 / np.maximum(cos_t, 1e-12))
            w = np.where(tinted, w * (1.0 + coat_w * (absorbed - 1.0)), w)
        return SimpleNamespace(through=1.0 - alpha, sheen=sheen, sheen_a=a, sheen_b=b, coat=coat, base=w,
                               sheen_albedo=r, coat_albedo=a_coat, coat_view=coat_view, alpha=alpha, bare=False)

    def _sheen_params(self, si: ShadingPoint, sheen_w: np.ndarray):
        """The sheen's (a, b, R) (N,) each where sheen_w > 0, 0 elsewhere (nothing reads them there:
        layer_weights sets R to 0, and the sheen's weight and probability are 0)."""
        on = sheen_w > 0.0
        rough = self.sheen_roughness.take(si.material)
        if on.all():
            return self.sheen.params(si, rough)
        a, b, r = np.zeros(len(si)), np.zeros(len(si)), np.zeros(len(si))
        idx = np.flatnonzero(on)
        if len(idx):
            a[idx], b[idx], r[idx] = self.sheen.params(si.take(idx), rough.take(idx))
        return a, b, r

    def _layered_lobes(self, si: ShadingPoint):
        """(layers, closure weights (3, N) of sheen, coat, metal, specular, diffuse (and glass where
        any material transmits), and the probabilities (6 or 7, N) of pass-through, sheen, coat,
        metal, specular, diffuse (, glass))."""
        layers = self.layer_weights(si)
        if self.compiled is not None:       # lobe_weights and the lines below in one pass (principled_jit.py)
            if not self.any_transmission:
                weights, prob = self.compiled.layered_lobes(self._compiled_lobe_inputs(si), layers)
                return layers, weights, prob
            glass = self._glass_setup(si)
            weights, prob = self.compiled.layered_lobes(self._compiled_lobe_inputs(si), layers, glass.w,
                                                        glass.sample_weight)
            return layers, weights, prob
        (w_metal, w_spec, w_diffuse), base_prob = self.lobe_weights(si, sample_total=True)
        base = layers.base
        weights = [layers.sheen, layers.coat, w_metal * base, w_spec * base, w_diffuse * base]
        coat_sample = layers.coat.mean(axis=0) * layers.coat_albedo
        sample = np.vstack([layers.sheen.mean(axis=0), coat_sample, base_prob * base.mean(axis=0)])
        if self.any_transmission:                   # the transmission closure: t (1 - metallic) W
            w_glass = self._glass_weight(si)
            weights.append(w_glass * base)
            sample = np.vstack([sample, w_glass * base.mean(axis=0) * self._glass_sample_weight(si, w_glass)])
        total = sample.sum(axis=0)
        alpha = 1.0 - layers.through
        opaque = np.where(total > 0.0, alpha, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            prob = np.where(total > 0.0, opaque * sample / total, 0.0)
        return layers, weights, np.vstack([1.0 - opaque, prob])

    def _layered_mixture(self, si: ShadingPoint, wi: np.ndarray, layers, weights, prob):
        """(f cos, pdf) of the non-delta lobes: the base's _mixture plus the sheen and the coat."""
        f_cos, pdf = np.zeros((3, len(si))), np.zeros(len(si))
        sheen = np.flatnonzero(weights[0].max(axis=0) > 0.0)
        if len(sheen):
            d = self.sheen.eval(si.take(sheen), wi.take(sheen, axis=1), layers.sheen_a.take(sheen),
                                layers.sheen_b.take(sheen))
            f_cos[:, sheen] += weights[0].take(sheen, axis=1) * d
            pdf[sheen] += prob[1].take(sheen) * d
        coat = np.flatnonzero(weights[1].max(axis=0) > 0.0)
        if len(coat):
            f_l, pdf_l = self.coat.eval(layers.coat_view.take(coat), wi.take(coat, axis=1))
            f_cos[:, coat] += weights[1].take(coat, axis=1) * f_l
            pdf[coat] += prob[2].take(coat) * pdf_l
        lobes, views = (self.metal, self.specular, self.diffuse), self._views(si)
        if len(weights) > 5:
            lobes, views = lobes + (self.glass,), views + (si,)
        for lobe, view, w, p in zip(lobes, views, weights[2:], prob[3:]):
            idx = np.flatnonzero(w.max(axis=0) > 0.0)
            if not len(idx):
                continue
            if len(idx) == len(si):                 # every hit: no gathers, the same numbers
                f_l, pdf_l = lobe.eval(view, wi)
                f_cos += w * f_l
                pdf += p * pdf_l
                continue
            f_l, pdf_l = lobe.eval(view.take(idx), wi.take(idx, axis=1))
            f_cos[:, idx] += w.take(idx, axis=1) * f_l
            pdf[idx] += p.take(idx) * pdf_l
        return f_cos, pdf

    def _glass_weight(self, si: ShadingPoint) -> np.ndarray:
        """The transmission closure's scalar weight t (1 - metallic) (N,), before W."""
        m = self.metallic.take(si.material)
        return self.glass.transmission.take(si.material) * np.where(1.0 - m > WEIGHT_CUTOFF, 1.0 - m, 0.0)

    def _glass_sample_weight(self, si: ShadingPoint, w_glass: np.ndarray) -> np.ndarray:
        """The transmission closure's albedo estimate (N,) where w_glass > 0, 0 elsewhere: there
        w_glass (0) x the base's mean x it is 0 either way (the estimate is finite and at least 0)."""
        on = w_glass > 0.0
        if on.all():
            return self.glass.sample_weight(si)
        out = np.zeros(len(si))
        idx = np.flatnonzero(on)
        if len(idx):
            out[idx] = self.glass.sample_weight(si.take(idx))
        return out

    def _glass_setup(self, si: ShadingPoint) -> SimpleNamespace:
        """The transmission closure at the hits for the compiled path, once per hit set (ShadingPoint.memo):
        its weight w (N,) (`_glass_weight`), its `setup` (principled_glass.py GlassSetup) at the hits
        where w > 0, rows (N,): each hit's place in it (-1 where w is 0), and the albedo estimate
        sample_weight (N,) from it (`_glass_sample_weight`'s numbers).  Its eval and sample read the
        setup by index (`_glass_rows`) instead of setting the closure up again on each take of the
        hits; the memo of a take gathers w, rows and sample_weight and keeps the setup whole, so a
        take's rows still index it."""
        def make(at):
            w_glass = self._glass_weight(at)
            idx = np.flatnonzero(w_glass > 0.0)
            rows = np.full(len(at), -1, dtype=np.int64)
            rows[idx] = np.arange(len(idx))
            setup = None if not len(idx) else self.glass.setup(at if len(idx) == len(at) else at.take(idx))
            if setup is not None and len(idx) == len(at):
                sample_weight = self.glass.sample_weight_at(setup)
            else:
                sample_weight = np.zeros(len(at))
                if len(idx):
                    sample_weight[idx] = self.glass.sample_weight_at(setup)
            return SimpleNamespace(w=w_glass, rows=rows, setup=setup, sample_weight=sample_weight)
        return si.memo((self, "glass setup"), make)

    @staticmethod
    def _glass_rows(glass: SimpleNamespace, at: np.ndarray):
        """The setup of `_glass_setup` (`glass`, of these hits or gathered for a take of them) at the
        hits `at`, or None where one of them has none (w 0: a hit whose lobe pick lands on the
        transmission closure only by the rounding of its probabilities): the setup itself where `at` are the hits it was set
        up at, in order; else its rows read (GlassSetup.at)."""
        if glass.setup is None:
            return None
        rows = glass.rows.take(at)
        if len(rows) == len(glass.setup) and np.array_equal(rows, np.arange(len(rows))):
            return glass.setup
        if (rows < 0).any():
            return None
        return glass.setup.at(rows)

    def _lobes_at(self, si: ShadingPoint):
        """_layered_lobes or lobe_weights at the hits (they depend on the hits, not on wi): once per hit for
        its eval and its sample (ShadingPoint.memo)."""
        return si.memo((self, "lobes"), self._layered_lobes if self.any_layers else self.lobe_weights)

    def _layered_sample(self, si: ShadingPoint, u_lobe, u) -> BSDFSample:
        """sample() with the layers: a lobe picked by u_lobe against the cumulative probabilities, its
        direction, and the mixture of every lobe at it (the NumPy reference of _compiled_layered_sample)."""
        layers, weights, prob = self._lobes_at(si)
        n = len(si)
        failed = np.zeros(n, dtype=bool)            # samples their own lobe rejected: value 0
        cdf = np.cumsum(prob, axis=0)
        choice = (np.asarray(u_lobe)[None, :] >= cdf[:-1]).sum(axis=0)   # 0 through, 1 sheen, 2 coat, 3.. base
        wi = np.zeros((3, n))
        flags = np.zeros(n, dtype=np.int8)
        through = np.flatnonzero(choice == 0)
        wi[:, through] = -si.wo[:, through]
        flags[through] = PASS_LOBE
        idx = np.flatnonzero(choice == 1)
        if len(idx):
            self._sample_sheen(si, idx, u, layers, wi, flags)
        views = (layers.coat_view,) + self._views(si)
        _sample_lobes((self.coat, self.metal, self.specular, self.diffuse), views, choice, 2, u, wi, flags,
                      failed if self.any_transmission else None)
        glass = np.flatnonzero(choice == 6)
        passed, crossing = self._sample_glass(si, glass, u_lobe, u, cdf[5].take(glass), prob, weights, wi, flags,
                                              failed)
        f_cos, pdf = self._layered_mixture(si, wi, layers, weights, prob)
        if crossing is not None:                    # weighed on this side of the surface, then crossed
            si.media.cross(*crossing)
        with np.errstate(divide="ignore", invalid="ignore"):
            value = np.where(pdf > 0.0, f_cos / pdf, 0.0)
            p_through = prob[0].take(through)
            value[:, through] = np.where(p_through > 0.0, layers.through.take(through) / p_through, 0.0)
        pdf[through] = prob[0].take(through)
        if passed is not None:                      # the glass's delta pass-through (index-matched)
            idx, weight = passed
            p_glass = prob[6].take(idx)
            with np.errstate(divide="ignore", invalid="ignore"):
                value[:, idx] = np.where(p_glass > 0.0, weights[5].take(idx, axis=1) * weight / p_glass, 0.0)
            pdf[idx] = p_glass
        if failed.any():
            value[:, failed], pdf[failed] = 0.0, 0.0
        return BSDFSample(wi, np.nan_to_num(value), pdf, flags)

    def _compiled_layered_sample(self, si: ShadingPoint, hits, u_lobe, u) -> BSDFSample:
        """_layered_sample on the compiled kernels (principled_jit.py, the same numbers): the lobe pick
        with the pass-through's and the GGX directions by layered_pick, the diffuse picks' directions
        by diffuse_directions, the sheen's and the transmission closure's in NumPy, the mixture by
        base_eval (and _add_glass), the throughput weights by sample_values."""
        layers, weights, prob = self._lobes_at(si)
        compiled = self.compiled
        wi, flags, choice, failed, counts = compiled.layered_pick(hits, u_lobe, u[0], u[1], PASS_LOBE)
        if not self.any_transmission:               # no lobe's failed sample is zeroed without it (NumPy's path)
            failed = None
        if counts[1]:
            self._sample_sheen(si, np.flatnonzero(choice == 1), u, layers, wi, flags)
        if counts[5]:
            compiled.diffuse_directions(np.flatnonzero(choice == 5), u[0], u[1], si.n, wi, failed)
        passed = crossing = None
        if counts[6]:                               # np.cumsum's row 5 at those hits: the same sums
            glass = np.flatnonzero(choice == 6)
            passed, crossing = self._sample_glass(si, glass, u_lobe, u,
                                                  np.cumsum(prob.take(glass, axis=1), axis=0)[5], prob, weights, wi,
                                                  flags, failed, self._glass_rows(hits.glass.setup, glass))
        f_cos, pdf = compiled.base_eval(hits, None, wi, self.metal_tint)
        self._add_glass(si, hits, None, wi, f_cos, pdf)
        if crossing is not None:                    # weighed on this side of the surface, then crossed
            si.media.cross(*crossing)
        value, pdf = compiled.sample_values(f_cos, pdf, choice, prob[0], layers.through, failed)
        if passed is not None:                      # the glass's delta pass-through (index-matched)
            idx, weight = passed
            p_glass = prob[6].take(idx)
            kept = ~failed.take(idx)
            with np.errstate(divide="ignore", invalid="ignore"):
                through = np.where(p_glass > 0.0, weights[5].take(idx, axis=1) * weight / p_glass, 0.0)
            value[:, idx] = np.nan_to_num(np.where(kept, through, 0.0))
            pdf[idx] = np.where(kept, p_glass, 0.0)
        return BSDFSample(wi, value, pdf, flags)

    def _sample_sheen(self, si: ShadingPoint, idx, u, layers, wi, flags):
        """The sheen's directions of the hits idx that picked it, written into wi and flags."""
        wi[:, idx] = self.sheen.sample(si.take(idx), u[0].take(idx), u[1].take(idx),
                                       layers.sheen_a.take(idx), layers.sheen_b.take(idx))
        flags[idx] = SHEEN_LOBE

    def _sample_glass(self, si, idx, u_lobe, u, below, prob, weights, wi, flags, failed, setup=None):
        """Directions of the hits idx that picked the transmission closure (into wi, flags, failed), with
        the closure-choice uniform rescaled to pick reflection or refraction (below: the cdf of the
        lobes before it at idx); setup: the closure's setup at idx when known (`_glass_rows`).  Returns
        ((indices, weight) of the delta pass-throughs, or None; the arguments of si.media.cross for the
        refracted paths, or None): the caller crosses after the mixture is weighed, whose transmission
        lobe reads the stack on this side of the surface."""
        if not len(idx):
            return None, None
        p = prob[6].take(idx)
        with np.errstate(divide="ignore", invalid="ignore"):
            u_fresnel = np.clip(np.nan_to_num((np.asarray(u_lobe).take(idx) - below) / p), 0.0, 1.0 - 1e-12)
        at = si.take(idx)
        d, weight, _, sampled, refracted, entering = self.glass.sample(at, u_fresnel, u[0].take(idx), u[1].take(idx),
                                                                       setup)
        wi[:, idx] = d
        flags[idx] = sampled
        failed[idx] = ~np.any(weight > 0.0, axis=0)
        crossing = None
        if si.media is not None:
            crossing = (idx.take(np.flatnonzero(refracted)), _scatter(entering, idx, len(si)),
                        _scatter(self.glass.ior.take(at.material), idx, len(si)))
        delta = np.flatnonzero((sampled & BSDFFlags.DELTA) != 0)
        return ((idx.take(delta), weight.take(delta, axis=1)) if len(delta) else None), crossing

    def _add_glass(self, si: ShadingPoint, hits, index, wi: np.ndarray, f_cos: np.ndarray, pdf: np.ndarray):
        """The transmission closure's f cos and pdf added into the compiled lobes' sums (in place) at
        the pairs (hit index[k], wi[:, k]) whose material transmits, as _layered_mixture adds it:
        last, from its setup at those hits (`_glass_setup`)."""
        if hits.glass is None:
            return
        on = hits.glass.on if index is None else hits.glass.on.take(index)
        k = np.flatnonzero(on)
        if not len(k):
            return
        at = k if index is None else index.take(k)
        every = index is None and len(k) == len(si)
        setup = self._glass_rows(hits.glass.setup, at)
        f_l, pdf_l = self.glass.eval(None, wi if every else wi.take(k, axis=1), setup)
        f_cos[:, k] += hits.glass.w.take(at, axis=1) * f_l
        pdf[k] += hits.glass.p.take(at) * pdf_l

    # -- the protocol -------------------------------------------------------------------------
    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.compiled is not None:
            hits, index = si.memo_at((self, "fused"), self._fused_hits)
            if hits is not None:
                f_cos, pdf = self.compiled.base_eval(hits, index, wi, self.metal_tint)
                self._add_glass(si, hits, index, wi, f_cos, pdf)
                return f_cos, pdf
        if self.any_layers:
            layers, weights, prob = self._lobes_at(si)
            return self._layered_mixture(si, wi, layers, weights, prob)
        weights, prob = self._lobes_at(si)
        return self._mixture(si, wi, weights, prob)

    def diffuse_part(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        """f cos (3, N) of the diffuse and sheen lobes alone, as weighted in eval: the closures Cycles
        counts as diffuse (CLOSURE_IS_BSDF_DIFFUSE), whose bump shadowing differs from the glossy
        ones' (engine/nodes/normals.py bump_shadowing; engine/integrators/path_tracer.py)."""
        if self.any_layers:
            layers, weights, prob = self._lobes_at(si)
            kept = [w if i in (0, 4) else np.zeros_like(w) for i, w in enumerate(weights)]
            return self._layered_mixture(si, wi, layers, kept, prob)[0]
        (w_metal, w_spec, w_diffuse), prob = self._lobes_at(si)
        return self._mixture(si, wi, (np.zeros_like(w_metal), np.zeros_like(w_spec), w_diffuse), prob)[0]

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        return self.eval(si, wi)[1]

    def sample(self, si: ShadingPoint, u_lobe, u) -> BSDFSample:
        if self.compiled is not None:
            hits = si.memo((self, "fused"), self._fused_hits)
            if hits is not None:
                if self.any_layers:
                    return self._compiled_layered_sample(si, hits, u_lobe, u)
                return self._compiled_sample(si, hits, u_lobe, u)
        if self.any_layers:
            return self._layered_sample(si, u_lobe, u)
        weights, prob = self._lobes_at(si)
        cdf = np.cumsum(prob, axis=0)
        choice = (np.asarray(u_lobe)[None, :] >= cdf[:2]).sum(axis=0)      # 0 metal, 1 specular, 2 diffuse
        choice = np.where(prob.sum(axis=0) > 0.0, choice, 2)
        wi = np.zeros((3, len(si)))
        flags = np.zeros(len(si), dtype=np.int8)
        _sample_lobes((self.metal, self.specular, self.diffuse), self._views(si), choice, 0, u, wi, flags)
        f_cos, pdf = self._mixture(si, wi, weights, prob)
        with np.errstate(divide="ignore", invalid="ignore"):
            value = np.where(pdf > 0.0, f_cos / pdf, 0.0)
        return BSDFSample(wi, np.nan_to_num(value), pdf, flags)


    def _compiled_sample(self, si: ShadingPoint, hits, u_lobe, u) -> BSDFSample:
        """sample() of the base on the compiled kernels: the same picks, directions and numbers."""
        wi, flags, diffuse = self.compiled.base_pick(hits, u_lobe, u[0], u[1])
        if len(diffuse):                            # the diffuse lobe's cosine directions
            self.compiled.diffuse_directions(diffuse, u[0], u[1], si.n, wi)
        f_cos, pdf = self.compiled.base_eval(hits, None, wi, self.metal_tint)
        value, pdf = self.compiled.sample_values(f_cos, pdf)
        return BSDFSample(wi, value, pdf, flags)


def _scatter(values: np.ndarray, idx: np.ndarray, n: int) -> np.ndarray:
    """values (len(idx),) placed at idx of an array of n (zeros elsewhere)."""
    out = np.zeros(n, dtype=values.dtype)
    out[idx] = values
    return out


def _read_at(rows: np.ndarray, mu: np.ndarray):
    """Where _read reads the tables: (flat index of the lower point, of the upper, weight t) (N,) each."""
    x = np.sqrt(np.clip(mu, 0.0, 1.0)) * (MU_POINTS - 1)
    j = np.minimum(x.astype(np.int64), MU_POINTS - 1)
    k = np.minimum(j + 1, MU_POINTS - 1)
    t = x - j
    base = rows * MU_POINTS
    return base + j, base + k, t


def _read(table: np.ndarray, rows: np.ndarray, mu: np.ndarray, at=None) -> np.ndarray:
    """table (M, MU_POINTS) at each hit's material row and mu (N,), linear in sqrt(mu) (`at`: _read_at's,
    when another table of the same shape is read at the same points)."""
    low, high, t = _read_at(rows, mu) if at is None else at
    flat = table.ravel()
    return (1.0 - t) * flat.take(low) + t * flat.take(high)


def _read_both(first: np.ndarray, second: np.ndarray, rows: np.ndarray, mu: np.ndarray):
    """_read of two tables at the same rows and mu (the points found once)."""
    at = _read_at(rows, mu)
    return _read(first, rows, mu, at), _read(second, rows, mu, at)
