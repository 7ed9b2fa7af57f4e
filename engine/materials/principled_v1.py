"""The Principled BSDF v1 (Blender 3.x) as Cycles 3.4 builds it from closures (its
kernel/svm/closure.h, case CLOSURE_BSDF_PRINCIPLED_ID; kernel/closure/bsdf_principled_diffuse.h,
bsdf_principled_sheen.h, bsdf_microfacet.h, bsdf_microfacet_multi.h; a public source: blender/cycles
at tag v3.4.0, src/kernel/).  Four closures, each with its own weight, none darkening another (3.4
does not layer: the diffuse is not attenuated by the specular albedo), and the glass closures of
the transmission (engine/materials/principled_v1_glass.py, weight W_g = transmission x (1 -
metallic)) where a material has it; with transmission t the diffuse and sheen weights take a factor
(1 - t) and the specular weight is 1 - W_g:

* diffuse, weight (1 - metallic) x base colour: Burley's diffuse with retro-reflection,
  f cos = cos_i / pi x [(1 - F_o / 2)(1 - F_i / 2) + R (F_o + F_i + F_o F_i (R - 1))],
  F = (1 - cos)^5, R = roughness x (1 + wo.wi) (PRINCIPLED_DIFFUSE_FULL);
* sheen, weight sheen x (1 - metallic) x mix(1, base / lum(base), sheen tint), lum the Rec. 709
  luminance (Cycles' linear_rgb_to_gray): f cos = (1 - wi.h)^5 cos_i (no 1 / pi, as Burley's);
* specular, weight 1: GGX reflection with the "interpolated" Fresnel
  F = mix(cspec0, 1, (F_d(wi.h, eta) - F0) / (1 - F0)), eta = 2 / (1 - sqrt(0.08 specular)) - 1,
  F0 = 0.08 specular, cspec0 = mix(0.08 specular x mix(1, base / lum'(base), specular tint), base,
  metallic) clamped to [0, 1] (lum' = 0.3 r + 0.6 g + 0.1 b, as closure.h); alpha = roughness^2
  stretched by the anisotropy as the v2 node's (engine/materials/principled.py principled_alphas).
  Distribution "GGX" (the node's default in 3.4), or any roughness <= 0.075: single scattering with
  the separable masking G1(wo) G1(wi).  "Multiscatter GGX" above roughness 0.075: Cycles runs Heitz
  et al.'s random walk (2016); we approximate it by its exact first order (GGX with the
  height-correlated G2 the walk's single-scattering term uses) times the energy compensation
  1 + F_ms (1 - E) / E of engine/materials/glossy.py (E from engine/materials/albedo_tables.py,
  F_ms from the interpolated Fresnel's hemispherical average): the same energy for a white surface,
  the multiple-scattering energy spread as the single-scattering lobe instead of the walk's wider
  one (docs/materials.md gives the measured difference);
* clearcoat, weight 1: F_d(wi.h, 1.5) x 0.25 clearcoat (interpolated from 0.04 at IOR 1.5 is the
  dielectric Fresnel itself) with Burley's GTR1 normal distribution of alpha = clearcoat
  roughness^2 and the separable masking of a fixed alpha 0.25.  Cycles 3.4 draws the clearcoat's
  directions from GGX visible normals of that alpha but reports the GTR1 pdf; we sample GTR1 itself
  (pdf = D(h) cos_h / (4 wo.h)), so sample and pdf agree: light-sampled clearcoat highlights are
  Cycles', BSDF-sampled clearcoat reflections of other surfaces are the GTR1 lobe's (Cycles': the
  sharper GGX lobe's; the lobe's weight is at most 0.25 F).

Filter Glossy (ShadingPoint.alpha_floor, engine/integrators/light_paths.py) raises the alphas of the
specular, the clearcoat and the glass closures to at least the floor, as Cycles 3.4's bsdf_blur
(docs/cycles34-filter-glossy.md); Burley's roughness and the single-or-multiple-scattering choice keep
the node's roughness, the multiscatter compensation follows the raised alphas (`blur_specular`).

Not here: subsurface (the exporter renders it as this diffuse, with a warning), clearcoat normal,
alpha.

Each closure is set up where Cycles sets it up (weights above CLOSURE_WEIGHT_CUTOFF).  Sampling
picks a closure with probability proportional to Cycles' sample_weight: the closure weight's
average times, for the specular and clearcoat lobes, the average Fresnel colour at wo.n
(bsdf_microfacet_fresnel_color) and, for the sheen, (1 - cos_o)^5 cos_o; eval and pdf are the sums
over the closures (one-sample MIS over closures, as Cycles' _shader_bsdf_multi_eval).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ..core.backend import JIT_MODULES, NUMBA
from ..core.vec import dot, normalize
from ..sampling.warps import cosine_hemisphere
from ..scene.model import PrincipledV1 as Params
from . import albedo_tables
from .glossy import fresnel_dielectric, fresnel_dielectric_average
from .microfacet import ALPHA_MIN, ggx_d, ggx_lambda, ggx_sample_vndf, shading_frame, to_local, to_world
from .principled import principled_alpha_rows, principled_alphas
from .principled_v1_glass import CLOSURES as GLASS_CLOSURES, PrincipledV1Glass, interpolated_fresnel
from .protocol import BSDF, BSDFFlags, BSDFSample, ShadingPoint
from .dielectric_lobe import REFLECTED, REFRACTED
from .textures import hit_tangent, per_hit, textured_mask

FLAGS = BSDFFlags.REFLECTION | BSDFFlags.DIFFUSE | BSDFFlags.GLOSSY
DIFFUSE_LOBE = BSDFFlags.REFLECTION | BSDFFlags.DIFFUSE
GLOSSY_LOBE = BSDFFlags.REFLECTION | BSDFFlags.GLOSSY
WEIGHT_CUTOFF = 1e-5                # Cycles' CLOSURE_WEIGHT_CUTOFF
SINGLE_SCATTER_ROUGHNESS = 0.075    # closure.h: at or below it "Multiscatter GGX" is single-scatter GGX
CLEARCOAT_IOR = 1.5
CLEARCOAT_G_ALPHA = 0.25            # the clearcoat's masking uses this fixed alpha (bsdf_microfacet.h)
LUMINANCE = np.array([0.2126729, 0.7151522, 0.0721750])[:, None]    # Rec. 709 Y (linear_rgb_to_gray)
TINT_LUMINANCE = np.array([0.3, 0.6, 0.1])[:, None]                 # closure.h's "luminance approx."
LOBES = ("diffuse", "sheen", "specular", "clearcoat") + GLASS_CLOSURES     # the glass: principled_v1_glass.py


def schlick_weight(cos):
    """(1 - cos)^5, cos clamped to [0, 1] (Cycles' schlick_fresnel)."""
    m = np.clip(1.0 - cos, 0.0, 1.0)
    return m * m * m * m * m


def specular_ior(specular):
    """The specular lobe's eta, 2 / (1 - sqrt(0.08 specular)) - 1: its F0 is 0.08 specular."""
    return 2.0 / (1.0 - np.sqrt(np.maximum(0.08 * np.asarray(specular, dtype=np.float64), 0.0))) - 1.0


def tint_colour(base, tint, luminance):
    """mix(1, base / lum(base), tint) (3, N), base / lum = 1 where lum <= 0 (hue and saturation only)."""
    lum = (base * luminance).sum(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        hue = np.where(lum > 0.0, base / np.where(lum > 0.0, lum, 1.0), 1.0)
    return (1.0 - tint) + hue * tint


def burley_diffuse(cos_o, cos_i, cos_oi, roughness):
    """Burley's diffuse with retro-reflection, f cos (N,) without the colour (bsdf_principled_diffuse.h,
    PRINCIPLED_DIFFUSE_FULL); 0 where cos_i <= 0."""
    fo, fi = schlick_weight(cos_o), schlick_weight(cos_i)
    rr = roughness * (cos_oi + 1.0)
    f = (1.0 - 0.5 * fo) * (1.0 - 0.5 * fi) + rr * (fi + fo + fi * fo * (rr - 1.0))
    return np.where(cos_i > 0.0, cos_i / np.pi * f, 0.0)


def gtr1_d(cos_h, alpha):
    """Burley's GTR1 (Berry) normal distribution, normalised: (a^2 - 1) / (pi ln(a^2) (1 + (a^2 - 1) cos^2))."""
    a2 = alpha * alpha
    lg = np.log(a2)
    t = 1.0 + (a2 - 1.0) * cos_h * cos_h
    return np.where(cos_h > 0.0, np.expm1(lg) / (np.pi * lg * t), 0.0)


def gtr1_sample(alpha, u1, u2):
    """A normal h (3, N) with density D_GTR1(h) cos_h: cos_h^2 = (1 - a^(2(1 - u1))) / (1 - a^2)."""
    lg = np.log(alpha * alpha)
    cos2 = np.clip(np.expm1((1.0 - u1) * lg) / np.expm1(lg), 0.0, 1.0)
    sin = np.sqrt(1.0 - cos2)
    phi = 2.0 * np.pi * u2
    return np.stack([sin * np.cos(phi), sin * np.sin(phi), np.sqrt(cos2)])


def blur_specular(hit: SimpleNamespace, floor: np.ndarray) -> None:
    """Filter Glossy on the specular closure's inputs (PrincipledV1.inputs): alphas raised to at least
    `floor` (N,) (Cycles 3.4 bsdf_blur, docs/cycles34-filter-glossy.md: fmaxf(roughness, alpha) on the
    (multi-)GGX closures), the albedo tables' roughness following the raised alphas where the floor
    raised them (3.4's random walk runs on the raised alphas, so our compensation of the walk's energy
    does too); the "Multiscatter GGX" choice and the Burley roughness keep the material's."""
    ax, ay = np.maximum(hit.ax, floor), np.maximum(hit.ay, floor)
    raised = (ax != hit.ax) | (ay != hit.ay)
    hit.table = np.where(raised, np.sqrt(np.sqrt(ax * ay)), hit.table)
    hit.ax, hit.ay = ax, ay


def _iso_lambda(w, alpha):
    return ggx_lambda(w, alpha, alpha)


class PrincipledV1(BSDF):
    """Blender 3.4's Principled BSDF of every material (engine/scene/model.py PrincipledV1):
    diffuse, sheen, specular and clearcoat closures (see the module)."""
    flags = FLAGS
    compiled = None                     # engine/materials/principled_v1_jit.py when the backend is numba

    def __init__(self, materials, settings):
        m = len(materials)
        params = [p if isinstance(p := getattr(x, "principled", None), Params) else Params() for x in materials]

        def column(values):
            return np.array(values, dtype=np.float64).reshape(m)
        self.metallic = column([min(max(p.metallic, 0.0), 1.0) for p in params])
        self.specular = column([max(p.specular, 0.0) for p in params])
        self.specular_tint = column([p.specular_tint for p in params])
        self.sheen = column([max(p.sheen, 0.0) for p in params])
        self.sheen_tint = column([p.sheen_tint for p in params])
        self.clearcoat = column([max(p.clearcoat, 0.0) for p in params])
        self.roughness = column([min(max(getattr(x, "roughness", 0.5), 0.0), 1.0) for x in materials])
        self.eta = specular_ior(self.specular)
        alphas = np.array([principled_alphas(getattr(x, "roughness", 0.5), getattr(x, "anisotropy", 0.0))
                           for x in materials], dtype=np.float64).reshape(m, 2)
        self.ax, self.ay = alphas[:, 0].copy(), alphas[:, 1].copy()
        self.roughness_of_table = np.sqrt(np.sqrt(self.ax * self.ay))
        self.multiscatter_menu = np.array([bool(getattr(x, "multiscatter", False)) for x in materials],
                                          dtype=bool).reshape(m)
        self.multiscatter = self.multiscatter_menu & (self.roughness > SINGLE_SCATTER_ROUGHNESS)
        self.anisotropy = column([getattr(x, "anisotropy", 0.0) for x in materials])
        self.cc_alpha = column([min(max(p.clearcoat_roughness, 0.0), 1.0) ** 2 for p in params])
        self.cc_alpha = np.clip(self.cc_alpha, ALPHA_MIN, 1.0 - 1e-6)
        self.tangent = np.array([getattr(x, "tangent", (1.0, 0.0, 0.0)) for x in materials],
                                dtype=np.float64).reshape(m, 3).T.copy()
        self.rotation = column([getattr(x, "rotation", 0.0) for x in materials])
        self.glass = PrincipledV1Glass(materials, params)
        if self.glass.any:                          # light from the far side too
            self.flags = FLAGS | REFLECTED | REFRACTED

    def use_backend(self, backends: dict) -> None:
        """The closures' eval and sample compiled (engine/materials/principled_v1_jit.py, the same
        numbers) when the render runs the Principled effects on numba and no material has a clearcoat
        or a transmission (those keep the NumPy closures)."""
        super().use_backend(backends)
        fusable = not self.glass.any and not bool((self.clearcoat > WEIGHT_CUTOFF).any())
        if fusable and any(backends.get(k) == NUMBA for k in JIT_MODULES["materials.principled_v1_jit"]):
            from . import principled_v1_jit
            self.compiled = principled_v1_jit
        else:
            self.compiled = None

    def _fused_hits(self, si: ShadingPoint) -> SimpleNamespace:
        """What the compiled closures read per hit (C-contiguous, over the hits on the last axis): wo,
        the frame x, y, n, the alphas, "Multiscatter GGX" flags and roughness, eta and the Fresnel's
        F0, cspec0, the specular compensation, the closure weights and probabilities."""
        weights, prob = si.memo((self, "closures"), self.closures)
        x, y = si.memo((self, "frame"), self._frame)
        hit = self._inputs(si)
        eta = self.eta.take(si.material)
        compensation = si.memo((self, "compensation"), lambda at: self._compensation(at, dot(at.wo, at.n)))
        rows = np.ascontiguousarray
        return SimpleNamespace(
            wo=rows(si.wo), x=rows(x), y=rows(y), n=rows(si.n), ax=rows(hit.ax), ay=rows(hit.ay),
            multi=rows(hit.multi), roughness=rows(hit.roughness), eta=rows(eta),
            f0=rows(fresnel_dielectric(np.ones(len(si)), eta)), cspec0=rows(self.cspec0(si)),
            comp=rows(compensation), w_diffuse=rows(weights[0]), w_sheen=rows(weights[1]), w_spec=rows(weights[2]),
            prob=rows(prob))

    def _compiled_sample(self, si: ShadingPoint, u_lobe, u) -> BSDFSample:
        """sample() on the compiled kernels: the same picks, directions and numbers."""
        hits = si.memo((self, "fused"), self._fused_hits)
        wi, choice = self.compiled.closures_pick(hits, u_lobe, u[0], u[1])
        flags = np.where(choice < 2, np.int8(DIFFUSE_LOBE), np.int8(GLOSSY_LOBE))
        for idx, code in ((np.flatnonzero(choice < 2), 0), (np.flatnonzero(choice == 3), 3)):
            if not len(idx):                        # cosine directions (NumPy's sin, cos), the clearcoat's
                continue
            x, y, n = (a.take(idx, axis=1) for a in (hits.x, hits.y, hits.n))
            wo_l = to_local(hits.wo.take(idx, axis=1), x, y, n) if code == 3 else None
            wi_l = self._sample_lobe(code, si.take(idx), wo_l, u[0].take(idx), u[1].take(idx))
            wi[:, idx] = normalize(to_world(wi_l, x, y, n))
        f_cos, pdf = self.compiled.closures_eval(hits, None, wi)
        with np.errstate(divide="ignore", invalid="ignore"):
            value = np.where(pdf > 0.0, f_cos / pdf, 0.0)
        return BSDFSample(wi, np.nan_to_num(value), pdf, flags)

    # -- per hit ------------------------------------------------------------------------------------
    def inputs(self, si: ShadingPoint) -> SimpleNamespace:
        """The hits' roughness, metallic, alphas ax, ay, "Multiscatter GGX" flags (above roughness
        0.075) and the roughness of the albedo tables (N,) each: the materials' own, or read per hit
        from their Roughness / Metallic image textures or node programs (engine/materials/textures.py
        per_hit; the exporter gives them only to materials without transmission, whose glass
        closures keep the material's); the alphas and the tables' roughness raised by Filter Glossy
        (`blur_specular`).  The compiled closures read these too."""
        mat = si.material
        metallic = np.clip(per_hit(si, self.metallic, "metallic"), 0.0, 1.0)
        out = SimpleNamespace(roughness=self.roughness.take(mat), metallic=metallic, ax=self.ax.take(mat),
                              ay=self.ay.take(mat), multi=self.multiscatter.take(mat),
                              table=self.roughness_of_table.take(mat))
        textured = textured_mask(si, "roughness")
        if textured is not None:
            r = np.clip(per_hit(si, self.roughness, "roughness"), 0.0, 1.0)
            ax, ay = principled_alpha_rows(r, self.anisotropy.take(mat))
            out.roughness = np.where(textured, r, out.roughness)
            out.ax, out.ay = np.where(textured, ax, out.ax), np.where(textured, ay, out.ay)
            out.multi = np.where(textured, self.multiscatter_menu.take(mat) & (r > SINGLE_SCATTER_ROUGHNESS),
                                 out.multi)
            out.table = np.where(textured, np.sqrt(np.sqrt(out.ax * out.ay)), out.table)
        if si.alpha_floor is not None:
            blur_specular(out, si.alpha_floor)
        return out

    def clearcoat_alpha(self, si: ShadingPoint) -> np.ndarray:
        """The clearcoat's GTR1 alpha (N,) at the hits: the material's, at least si.alpha_floor (Filter
        Glossy: bsdf_blur raises CLOSURE_BSDF_MICROFACET_GGX_CLEARCOAT_ID's alpha_x, the GTR1's alpha;
        the masking keeps its fixed 0.25)."""
        alpha = self.cc_alpha.take(si.material)
        return alpha if si.alpha_floor is None else np.maximum(alpha, si.alpha_floor)

    def _inputs(self, si: ShadingPoint) -> SimpleNamespace:
        return si.memo((self, "inputs"), self.inputs)

    def _frame(self, si: ShadingPoint):
        x, y = shading_frame(si.n, hit_tangent(si, self.tangent))
        turn = 2.0 * np.pi * self.rotation.take(si.material)
        if np.any(turn != 0.0):
            c, s = np.cos(turn), np.sin(turn)
            x, y = c * x + s * y, c * y - s * x
        return x, y

    def cspec0(self, si: ShadingPoint) -> np.ndarray:
        """The specular lobe's colour at normal incidence (3, N), clamped to [0, 1]."""
        mat, base = si.material, si.color
        metal = self._inputs(si).metallic
        tint = tint_colour(base, self.specular_tint.take(mat), TINT_LUMINANCE)
        dielectric = 0.08 * self.specular.take(mat) * tint
        return np.clip(dielectric * (1.0 - metal) + base * metal, 0.0, 1.0)

    def closures(self, si: ShadingPoint):
        """(weights, probabilities): each closure's weight per hit (3, N), zero where Cycles does not
        set it up, in LOBES order, and the probability (4, N) of sampling each (Cycles' sample_weight);
        where any material transmits, 7 closures (the glass's three last, principled_v1_glass.py)."""
        mat, base = si.material, si.color
        n = len(si)
        cos_o = np.clip(dot(si.wo, si.n), 0.0, 1.0)
        metallic = self._inputs(si).metallic
        dw = 1.0 - metallic
        if self.glass.any:                          # diffuse_weight = (1 - metallic)(1 - transmission)
            dw = dw * (1.0 - self.glass.transmission.take(mat))
        on_diffuse = dw > WEIGHT_CUTOFF
        w_diffuse = np.where(on_diffuse & (np.abs(base.mean(axis=0)) > WEIGHT_CUTOFF), base * dw, 0.0)
        sheen = self.sheen.take(mat)
        w_sheen = sheen * tint_colour(base, self.sheen_tint.take(mat), LUMINANCE) * dw
        w_sheen = np.where(on_diffuse & (sheen > WEIGHT_CUTOFF), w_sheen, 0.0)
        on_spec = (self.specular.take(mat) > WEIGHT_CUTOFF) | (metallic > WEIGHT_CUTOFF)
        w_spec = np.where(on_spec, 1.0, 0.0) * np.ones((3, n))
        if self.glass.any:                          # specular_weight = 1 - (1 - metallic) transmission
            spec_weight = 1.0 - self.glass.weight.take(mat)
            w_spec = np.where(spec_weight > WEIGHT_CUTOFF, spec_weight, 0.0) * w_spec
        cc = self.clearcoat.take(mat)
        w_cc = np.where(cc > WEIGHT_CUTOFF, 1.0, 0.0) * np.ones((3, n))
        # bsdf_alloc drops closures whose weight averages below the cutoff
        weights = [np.where(w.mean(axis=0) >= WEIGHT_CUTOFF, w, 0.0) for w in (w_diffuse, w_sheen, w_spec, w_cc)]
        f_spec = interpolated_fresnel(cos_o, self.eta.take(mat), self.cspec0(si))
        f_cc = 0.25 * cc * fresnel_dielectric(cos_o, np.full(n, CLEARCOAT_IOR))
        w_diffuse, w_sheen, w_spec, w_cc = weights
        sample = np.stack([w_diffuse.mean(axis=0), w_sheen.mean(axis=0) * schlick_weight(cos_o) * cos_o,
                           w_spec.mean(axis=0) * f_spec.mean(axis=0), w_cc.mean(axis=0) * f_cc])
        if self.glass.any:
            glass, glass_sample = self.glass.closures(si)
            weights = weights + glass
            sample = np.vstack([sample, glass_sample])
        total = sample.sum(axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            prob = np.where(total > 0.0, sample / np.where(total > 0.0, total, 1.0), 0.0)
        return weights, prob

    # -- the lobes (f cos without the closure weight, and pdf), directions in the local frame ------
    def _diffuse(self, si, wo_l, wi_l):
        f = burley_diffuse(wo_l[2], wi_l[2], dot(wo_l, wi_l), self._inputs(si).roughness)
        return f[None, :] * np.ones((3, 1)), np.maximum(wi_l[2], 0.0) / np.pi

    def _sheen(self, si, wo_l, wi_l):
        h = normalize(wo_l + wi_l)
        ok = (wi_l[2] > 0.0) & (wo_l[2] >= 0.0)
        f = np.where(ok, schlick_weight(dot(wi_l, h)) * wi_l[2], 0.0)
        return f[None, :] * np.ones((3, 1)), np.maximum(wi_l[2], 0.0) / np.pi

    def _specular(self, si, wo_l, wi_l):
        mat = si.material
        hit = self._inputs(si)
        ax, ay = hit.ax, hit.ay
        ok = (wo_l[2] > 0.0) & (wi_l[2] > 0.0)
        h = normalize(wo_l + wi_l)
        lo, li = ggx_lambda(wo_l, ax, ay), ggx_lambda(wi_l, ax, ay)
        multi = hit.multi
        with np.errstate(divide="ignore", invalid="ignore"):
            common = np.where(ok, ggx_d(h, ax, ay) / (4.0 * wo_l[2]), 0.0)
            g = np.where(multi, 1.0 / (1.0 + lo + li), 1.0 / ((1.0 + lo) * (1.0 + li)))
            pdf = np.nan_to_num(common / (1.0 + lo))
            f = np.nan_to_num(common * g)
        fresnel = interpolated_fresnel(np.clip(dot(wi_l, h), 0.0, 1.0), self.eta.take(mat), self.cspec0(si))
        # wo_l[2] is dot(si.wo, si.n) (to_local): the same per hit in eval and sample, kept once
        compensation = si.memo((self, "compensation"), lambda at: self._compensation(at, dot(at.wo, at.n)))
        return fresnel * f * compensation, pdf

    def _compensation(self, si, cos_o):
        """1 + F_ms (1 - E) / E (3, N) where the material is "Multiscatter GGX" above roughness 0.075,
        1 elsewhere (the approximation of the module)."""
        hit = self._inputs(si)
        multi = hit.multi
        if not multi.any():
            return np.ones((3, len(si)))
        mat = si.material
        rough = hit.table
        e = albedo_tables.albedo(rough, np.clip(cos_o, 0.0, 1.0))
        e_avg = albedo_tables.average_albedo(rough)
        eta = self.eta.take(mat)
        f0 = fresnel_dielectric(np.ones(len(si)), eta)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.clip(np.where(f0 < 1.0, (fresnel_dielectric_average(eta) - f0) / (1.0 - f0), 1.0), 0.0, 1.0)
            f_ss = self.cspec0(si) * (1.0 - s) + s
            f_ms = f_ss * e_avg / (1.0 - f_ss * (1.0 - e_avg))
            scale = 1.0 + f_ms * np.where(e > 0.0, (1.0 - e) / e, 0.0)
        return np.where(multi, scale, 1.0)

    def _clearcoat(self, si, wo_l, wi_l):
        mat = si.material
        alpha = self.clearcoat_alpha(si)
        ok = (wo_l[2] > 0.0) & (wi_l[2] > 0.0)
        h = normalize(wo_l + wi_l)
        d = gtr1_d(h[2], alpha)
        g = 1.0 / ((1.0 + _iso_lambda(wo_l, CLEARCOAT_G_ALPHA)) * (1.0 + _iso_lambda(wi_l, CLEARCOAT_G_ALPHA)))
        cos_h = np.clip(dot(wo_l, h), 0.0, 1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            f = np.where(ok, d * g / (4.0 * wo_l[2]), 0.0)
            pdf = np.where(ok & (cos_h > 0.0), d * h[2] / (4.0 * cos_h), 0.0)
        fresnel = 0.25 * self.clearcoat.take(mat) * fresnel_dielectric(cos_h, np.full(len(si), CLEARCOAT_IOR))
        return (np.nan_to_num(f) * fresnel)[None, :] * np.ones((3, 1)), np.nan_to_num(pdf)

    def _sample_lobe(self, code, si, wo_l, u1, u2):
        """A local direction drawn from lobe `code` (the lobe's own density)."""
        if code in (0, 1):
            return cosine_hemisphere(u1, u2)
        if code == 2:
            hit = self._inputs(si)
            h = ggx_sample_vndf(wo_l, hit.ax, hit.ay, u1, u2)
        else:
            h = gtr1_sample(self.clearcoat_alpha(si), u1, u2)
        return 2.0 * dot(wo_l, h) * h - wo_l

    def _mixture(self, si, wo_l, wi_l, weights, prob):
        f_cos, pdf = np.zeros((3, len(si))), np.zeros(len(si))
        lobes = (self._diffuse, self._sheen, self._specular, self._clearcoat)
        if len(weights) > len(lobes):
            lobes = lobes + tuple((lambda s, o, i, code=code: self.glass.eval(code, s, o, i)) for code in range(3))
        for code, lobe in enumerate(lobes):
            w, p = weights[code], prob[code]
            idx = np.flatnonzero(w.max(axis=0) > 0.0)
            if not len(idx):
                continue
            f_l, pdf_l = lobe(si.take(idx), wo_l.take(idx, axis=1), wi_l.take(idx, axis=1))
            f_cos[:, idx] += w.take(idx, axis=1) * f_l
            pdf[idx] += p.take(idx) * pdf_l
        return f_cos, pdf

    # -- the protocol -------------------------------------------------------------------------------
    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.compiled is not None:
            hits, index = si.memo_at((self, "fused"), self._fused_hits)
            return self.compiled.closures_eval(hits, index, wi)
        weights, prob = si.memo((self, "closures"), self.closures)
        x, y = si.memo((self, "frame"), self._frame)
        return self._mixture(si, to_local(si.wo, x, y, si.n), to_local(wi, x, y, si.n), weights, prob)

    def diffuse_part(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        """f cos (3, N) of the diffuse and sheen closures alone (Cycles' CLOSURE_IS_BSDF_DIFFUSE, whose
        bump shadowing differs: engine/nodes/normals.py bump_shadowing)."""
        weights, prob = si.memo((self, "closures"), self.closures)
        kept = [w if code < 2 else np.zeros_like(w) for code, w in enumerate(weights)]
        x, y = si.memo((self, "frame"), self._frame)
        return self._mixture(si, to_local(si.wo, x, y, si.n), to_local(wi, x, y, si.n), kept, prob)[0]

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        return self.eval(si, wi)[1]

    def sample(self, si: ShadingPoint, u_lobe, u) -> BSDFSample:
        if self.compiled is not None:
            return self._compiled_sample(si, u_lobe, u)
        weights, prob = si.memo((self, "closures"), self.closures)
        x, y = si.memo((self, "frame"), self._frame)
        wo_l = to_local(si.wo, x, y, si.n)
        cdf = np.cumsum(prob, axis=0)
        last = len(prob) - 1
        choice = (np.asarray(u_lobe)[None, :] >= cdf[:last]).sum(axis=0)
        choice = np.where(prob.sum(axis=0) > 0.0, np.minimum(choice, last), 0)
        wi_l = np.zeros((3, len(si)))
        flags = np.full(len(si), GLOSSY_LOBE, dtype=np.int8)
        for code in range(4):
            idx = np.flatnonzero(choice == code)
            if not len(idx):
                continue
            wi_l[:, idx] = self._sample_lobe(code, si.take(idx), wo_l.take(idx, axis=1),
                                             u[0].take(idx), u[1].take(idx))
            if code < 2:
                flags[idx] = DIFFUSE_LOBE
        failed, crossings = None, []
        if last > 3:            # with the glass, a reflection drawn below the surface must not count its refraction
            failed, crossings = self._sample_glass(si, choice, u_lobe, u, cdf, prob, wo_l, wi_l, flags)
            failed |= (choice < 4) & (wi_l[2] <= 0.0)
        wi = normalize(to_world(wi_l, x, y, si.n))
        # evaluated from the world direction, exactly as eval() does (peaked lobes amplify rounding)
        f_cos, pdf = self._mixture(si, wo_l, to_local(wi, x, y, si.n), weights, prob)
        for crossing in crossings:          # weighed on this side of the surface, then crossed
            si.media.cross(*crossing)
        with np.errstate(divide="ignore", invalid="ignore"):
            value = np.where(pdf > 0.0, f_cos / pdf, 0.0)
        if failed is not None and failed.any():      # a rejected glass sample: no direction
            value[:, failed], pdf[failed] = 0.0, 0.0
        return BSDFSample(wi, np.nan_to_num(value), pdf, flags)

    def _sample_glass(self, si, choice, u_lobe, u, cdf, prob, wo_l, wi_l, flags):
        """Local directions (into wi_l, flags) of the hits that picked a glass closure (codes 4-6),
        the closure-choice uniform rescaled for the multiscatter glass's reflect-or-refract choice.
        Returns the rejected samples and the arguments of si.media.cross for the refracted paths: the
        caller crosses after the mixture is weighed, whose glass reads the stack on this side."""
        crossings = []
        failed = np.zeros(len(si), dtype=bool)
        for code in range(4, 7):
            idx = np.flatnonzero(choice == code)
            if not len(idx):
                continue
            p = prob[code].take(idx)
            with np.errstate(divide="ignore", invalid="ignore"):
                u_fresnel = np.clip(np.nan_to_num((np.asarray(u_lobe).take(idx) - cdf[code - 1].take(idx)) / p),
                                    0.0, 1.0 - 1e-12)
            at = si.take(idx)
            d, refracted, entering = self.glass.sample(code - 4, at, wo_l.take(idx, axis=1), u_fresnel,
                                                       u[0].take(idx), u[1].take(idx))
            rejected = ~np.any(d != 0.0, axis=0)
            wi_l[:, idx] = np.where(rejected, np.array([[0.0], [0.0], [1.0]]), d)
            flags[idx] = np.where(refracted, np.int8(REFRACTED), np.int8(GLOSSY_LOBE))
            failed[idx] = rejected
            if si.media is not None and refracted.any():
                n = len(si)
                crossed = idx.take(np.flatnonzero(refracted))
                enter, ior = np.zeros(n, dtype=bool), np.ones(n)
                enter[idx], ior[idx] = entering, self.glass.ior.take(at.material)
                crossings.append((crossed, enter, ior))
        return failed, crossings
