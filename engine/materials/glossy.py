"""Rough (microfacet) reflection as Cycles renders it (its bsdf_microfacet.h and svm closure.h, a
public source: blender/cycles src/kernel/): the distributions of engine/materials/microfacet.py,

    f cos(wi) = F(wo.h) D(h) G2(wo, wi) / (4 cos(wo)) * compensation(wo),   h = (wo + wi) / |wo + wi|,

sampled by visible normals, so that the weight f cos / pdf = F G2 / G1(wo) is computed as that
ratio (pdf = G1(wo) D(h) / (4 cos(wo)), exact).  The Fresnel term per material (`Material.fresnel`):

* "none": F = the colour, constant: Blender's Glossy / Anisotropic BSDF node (the colour is the
  closure's weight, Cycles' MicrofacetFresnel::NONE).
* "dielectric": F = colour x the dielectric Fresnel of the IOR (Cycles' DIELECTRIC_TINT, the
  Principled BSDF's specular layer with its tint).
* "conductor": F = the conductor Fresnel of the complex IOR n + ik per channel (the Metallic
  BSDF node, "Physical Conductor", Blender 4.3+).
* "f82": F82-tint (Kutz et al., "Novel aspects of the Adobe Standard Material"): Schlick from
  F0 = the colour, bent at 82 degrees by `edge_tint` (the Metallic BSDF node's default and the
  Principled BSDF's metallic lobe in 4.x).
* "interpolated": the dielectric Fresnel of the IOR rescaled from its F0 .. 1 to colour .. 1
  (Blender 3.4's Principled v1 specular, Cycles' interpolate_fresnel_color).

Multiple scattering (`Material.multiscatter`, GGX only; Cycles 4.x's "Multiscatter GGX",
microfacet_ggx_preserve_energy): the single-scatter lobe is scaled by 1 + F_ms (1 - E) / E with
E = E(cos(wo), roughness) and F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)), F_ss the Fresnel's
hemispherical average (engine/materials/albedo_tables.py); it depends on wo only, as in Cycles, so
the compensated lobe is not exactly reciprocal.

An image texture on the roughness (engine/scene/model.py Material.input_textures) gives each hit its
own alphas (`alphas`; `alpha_rule` maps roughness and anisotropy, the Principled lobes set theirs) and
table roughness; a tangent from the mesh (Material.tangent_source) replaces the material's tangent
at the hits that have one (engine/materials/textures.py per_hit, hit_tangent).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ..core.backend import JIT_MODULES, NUMBA
from ..core.vec import dot, normalize
from . import albedo_tables
from .microfacet import (BECKMANN, D, GGX, LAMBDA, SAMPLE_VNDF, glossy_alpha_rows, glossy_alphas, shading_frame,
                         to_local, to_world)
from .protocol import BSDF, BSDFFlags, BSDFSample, ShadingPoint
from .specular import specular_normal_at
from .textures import hit_tangent, per_hit, textured_mask

LOBE = BSDFFlags.GLOSSY | BSDFFlags.REFLECTION
FRESNEL_KINDS = ("none", "dielectric", "conductor", "f82", "interpolated")


def fresnel_dielectric(cos: np.ndarray, ior: np.ndarray) -> np.ndarray:
    """Unpolarised Fresnel reflectance from air into a dielectric of index `ior` (Cycles'
    fresnel_dielectric_cos), cos = wo.h >= 0; 1 under total internal reflection (ior < 1)."""
    g2 = ior * ior - 1.0 + cos * cos
    tir = g2 < 0.0
    g = np.sqrt(np.maximum(g2, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (g - cos) / (g + cos)
        b = (cos * (g + cos) - 1.0) / (cos * (g - cos) + 1.0)
        f = 0.5 * a * a * (1.0 + b * b)
    return np.where(tir, 1.0, np.clip(np.nan_to_num(f, nan=1.0), 0.0, 1.0))


def fresnel_dielectric_average(ior: np.ndarray) -> np.ndarray:
    """Hemispherical average of the dielectric Fresnel, Kulla & Conty's fit (as Cycles'
    fresnel_dielectric_Fss)."""
    ior = np.asarray(ior, dtype=np.float64)
    return np.where(ior < 1.0, 0.997118 + ior * (0.1014 - ior * (0.965241 + ior * 0.130607)),
                    (ior - 1.0) / (4.08567 + 1.00071 * ior))


def fresnel_conductor(cos: np.ndarray, n: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Unpolarised reflectance (3, N) of a conductor n + ik (rows (3, N)) seen from air at cos (N,)
    (Born & Wolf 14.4.1, as Cycles' fresnel_conductor)."""
    c2 = cos * cos
    t1 = n * n - k * k - (1.0 - c2)
    t2 = np.sqrt(t1 * t1 + (2.0 * n * k) ** 2)
    u2, v2 = np.maximum(0.5 * (t2 + t1), 0.0), np.maximum(0.5 * (t2 - t1), 0.0)
    u, v = np.sqrt(u2), np.sqrt(v2)
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = ((cos - u) ** 2 + v2) / ((cos + u) ** 2 + v2)
        t3, t4 = (n * n - k * k) * cos, 2.0 * n * k * cos
        rp = ((t3 - u) ** 2 + (t4 - v) ** 2) / ((t3 + u) ** 2 + (t4 + v) ** 2)
    return np.nan_to_num(0.5 * (rs + rp), nan=1.0)


F82_POW5 = (6.0 / 7.0) ** 5                        # f82_b's (1 - cos)^5 at cos = 1/7
F82_SCALE = 7.0 / (F82_POW5 * (6.0 / 7.0))         # and its 1 / (cos (1 - cos)^6) there


def f82_b(f0: np.ndarray, tint: np.ndarray) -> np.ndarray:
    """The F82-tint model's b: Schlick at cos = 1/7 times `tint` there (Cycles' fresnel_f82tint_B)."""
    return (f0 + (1.0 - f0) * F82_POW5) * F82_SCALE * (1.0 - tint)


def fresnel_f82(cos: np.ndarray, f0: np.ndarray, b: np.ndarray) -> np.ndarray:
    """F82-tint: Schlick(F0) - b cos (1 - cos)^6, clamped to [0, 1]."""
    s = np.clip(1.0 - cos, 0.0, 1.0)
    s5 = s ** 5
    return np.clip(f0 + (1.0 - f0) * s5 - b * cos * s5 * s, 0.0, 1.0)


def f82_b_from_f82(f0: np.ndarray, f82: np.ndarray) -> np.ndarray:
    """b such that the F82 model passes through f82 at cos = 1/7 (Cycles' fresnel_f82_B)."""
    f = 6.0 / 7.0
    f5 = f ** 5
    return (f0 + (1.0 - f0) * f5 - f82) * (7.0 / (f5 * f))


def f82_average(f0: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hemispherical average of the F82 model: mix(F0, 1, 1/21) - b / 126 (Cycles' fresnel_f82_Fss)."""
    return f0 + (1.0 - f0) / 21.0 - b / 126.0


def _column(values, m) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).reshape(m, 3).T.copy()


class MicrofacetReflection(BSDF):
    """Rough reflection of the glossy materials: per material alpha_x, alpha_y (from roughness
    and anisotropy, engine/materials/microfacet.py glossy_alphas), the tangent (world space,
    turned by rotation x 2 pi about the normal), the distribution, the Fresnel and compensation."""
    flags = LOBE
    roughness_input = "roughness"       # the textured input its roughness reads (None: none, the coat)
    alpha_rule = staticmethod(glossy_alpha_rows)    # (roughness, anisotropy) rows -> (alpha_x, alpha_y)
    compiled = None                     # engine/materials/microfacet_jit.py when the backend is numba

    def __init__(self, materials, settings):
        m = len(materials)
        self.roughness = np.array([getattr(x, "roughness", 0.5) for x in materials], dtype=np.float64).reshape(m)
        self.anisotropy = np.array([getattr(x, "anisotropy", 0.0) for x in materials], dtype=np.float64).reshape(m)
        alphas = np.array([glossy_alphas(getattr(x, "roughness", 0.5), getattr(x, "anisotropy", 0.0))
                           for x in materials], dtype=np.float64).reshape(m, 2)
        self.ax, self.ay = alphas[:, 0], alphas[:, 1]
        self.roughness_of_table = np.sqrt(np.sqrt(self.ax * self.ay))       # Cycles' `rough` lookup
        self.beckmann = np.array([getattr(x, "distribution", GGX) == BECKMANN for x in materials], dtype=bool)
        self.fresnel = np.array([FRESNEL_KINDS.index(getattr(x, "fresnel", "none")) for x in materials],
                                dtype=np.int8)
        self.ior = np.array([x.ior for x in materials], dtype=np.float64)
        self.n = _column([getattr(x, "conductor_ior", (0.18, 0.42, 1.37)) for x in materials], m)
        self.k = _column([getattr(x, "conductor_k", (3.42, 2.35, 1.77)) for x in materials], m)
        self.edge_tint = _column([getattr(x, "edge_tint", (1.0, 1.0, 1.0)) for x in materials], m)
        self.tangent = _column([getattr(x, "tangent", (1.0, 0.0, 0.0)) for x in materials], m)
        self.rotation = np.array([getattr(x, "rotation", 0.0) for x in materials], dtype=np.float64)
        self.compensate = np.array([getattr(x, "multiscatter", True) and getattr(x, "distribution", GGX) == GGX
                                    for x in materials], dtype=bool)
        # every Fresnel is the colour (the Glossy BSDF node): the compiled eval takes the colour as F
        self.tinted = bool(m) and bool((self.fresnel == FRESNEL_KINDS.index("none")).all())

    def use_backend(self, backends: dict) -> None:
        """The GGX geometry of eval and sample compiled (engine/materials/microfacet_jit.py, the
        same numbers) when the render runs the microfacet effects on numba."""
        if any(backends.get(k) == NUMBA for k in JIT_MODULES["materials.microfacet_jit"]):
            from . import microfacet_jit
            self.compiled = microfacet_jit
        else:
            self.compiled = None
        super().use_backend(backends)

    # -- per hit ------------------------------------------------------------------------------
    def alphas(self, si: ShadingPoint) -> tuple[np.ndarray, np.ndarray]:
        """(alpha_x, alpha_y) (N,): the material's, or from the roughness texture at textured hits;
        the material's own roughness (energy compensation, layer weights: `table_roughness`).  Hits of
        a span read a texture or node program once for the sample, the evals and the compensation
        (ShadingPoint.memo); hits of no span (tests may set a field between calls) each time."""
        if textured_mask(si, self.roughness_input) is None:
            return self.ax.take(si.material), self.ay.take(si.material)
        if si._shared or si._source is not None:
            return si.memo((self, "alphas"), self._alphas_read)
        return self._alphas_read(si)

    def _alphas_read(self, si: ShadingPoint) -> tuple[np.ndarray, np.ndarray]:
        mat = si.material
        ax, ay = self.ax.take(mat), self.ay.take(mat)
        textured = textured_mask(si, self.roughness_input)
        if textured is None:
            return ax, ay
        tx, ty = self.alpha_rule(per_hit(si, self.roughness, self.roughness_input), self.anisotropy.take(mat))
        return np.where(textured, tx, ax), np.where(textured, ty, ay)

    def _alphas(self, si: ShadingPoint):
        """(alpha_x, alpha_y, beckmann) of each hit for the lobe itself: `alphas`, at least
        si.alpha_floor (Filter Glossy, engine/integrators/light_paths.py)."""
        ax, ay = self.alphas(si)
        if si.alpha_floor is not None:
            ax, ay = np.maximum(ax, si.alpha_floor), np.maximum(ay, si.alpha_floor)
        return ax, ay, self.beckmann.take(si.material)

    def table_roughness(self, si: ShadingPoint) -> np.ndarray:
        """The albedo tables' roughness (N,) at the hits, sqrt of the alphas' geometric mean (Cycles' `rough`)."""
        base = self.roughness_of_table.take(si.material)
        textured = textured_mask(si, self.roughness_input)
        if textured is None:
            return base
        ax, ay = self.alphas(si)
        return np.where(textured, np.sqrt(np.sqrt(ax * ay)), base)

    def _frame(self, si: ShadingPoint):
        mat = si.material
        n = specular_normal_at(si)
        if self.compiled is not None:               # microfacet_jit.frame: shading_frame's numbers
            x, y = self.compiled.frame(n, hit_tangent(si, self.tangent))
        else:
            x, y = shading_frame(n, hit_tangent(si, self.tangent))
        turn = 2.0 * np.pi * self.rotation.take(mat)
        if np.any(turn != 0.0):
            c, s = np.cos(turn), np.sin(turn)
            x, y = c * x + s * y, c * y - s * x
        return x, y, n

    def _kinds(self, mat: np.ndarray):
        """(Fresnel code, its hits) for each Fresnel kind among the hits of materials `mat`: every
        hit (a slice, no gather) where all materials of the lobe have one kind."""
        if self.fresnel.size and (self.fresnel == self.fresnel[0]).all():
            return [(self.fresnel[0], slice(None))] if len(mat) else []
        kind = self.fresnel.take(mat)
        return [(code, np.flatnonzero(kind == code)) for code in np.unique(kind)]

    @staticmethod
    def _at(a, sel, axis=0):
        return a if isinstance(sel, slice) else a.take(sel, axis=axis)

    def _fresnel(self, si: ShadingPoint, cos: np.ndarray) -> np.ndarray:
        """F (3, N) at cos = wo.h, times the colour where the colour tints (all but conductors)."""
        mat, color = si.material, si.color
        f = color.copy()
        at = self._at
        for code, sel in self._kinds(mat):
            c, m, col = at(cos, sel), at(mat, sel), at(color, sel, 1)
            name = FRESNEL_KINDS[code]
            if name == "none":
                continue
            if name == "dielectric":
                f[:, sel] = col * fresnel_dielectric(c, self.ior.take(m))
            elif name == "conductor":
                f[:, sel] = fresnel_conductor(c, self.n.take(m, axis=1), self.k.take(m, axis=1))
            elif name == "f82":
                f0 = np.clip(col, 0.0, 1.0)
                f[:, sel] = fresnel_f82(c, f0, f82_b(f0, np.clip(self.edge_tint.take(m, axis=1), 0.0, 1.0)))
            else:                                                   # interpolated (3.4)
                ior = self.ior.take(m)
                real0 = fresnel_dielectric(np.ones_like(c), ior)
                with np.errstate(divide="ignore", invalid="ignore"):
                    s = np.where(real0 < 1.0, (fresnel_dielectric(c, ior) - real0) / (1.0 - real0), 1.0)
                f[:, sel] = col + (1.0 - col) * s
        return f

    def _fresnel_average(self, si: ShadingPoint) -> np.ndarray:
        """F_ss (3, N), the hemispherical average of F (Cycles' *_Fss)."""
        mat, color = si.material, si.color
        f = color.copy()
        at = self._at
        for code, sel in self._kinds(mat):
            m, col = at(mat, sel), at(color, sel, 1)
            count = len(m)
            name = FRESNEL_KINDS[code]
            if name == "dielectric":
                f[:, sel] = col * fresnel_dielectric_average(self.ior.take(m))
            elif name == "conductor":
                n, k = self.n.take(m, axis=1), self.k.take(m, axis=1)
                f0 = fresnel_conductor(np.ones(count), n, k)
                f82 = fresnel_conductor(np.full(count, 1.0 / 7.0), n, k)
                f[:, sel] = np.clip(f82_average(f0, f82_b_from_f82(f0, f82)), 0.0, 1.0)
            elif name == "f82":
                f0 = np.clip(col, 0.0, 1.0)
                f[:, sel] = f82_average(f0, f82_b(f0, np.clip(self.edge_tint.take(m, axis=1), 0.0, 1.0)))
            elif name == "interpolated":
                ior = self.ior.take(m)
                real0 = fresnel_dielectric(np.ones(count), ior)
                with np.errstate(divide="ignore", invalid="ignore"):
                    s = np.clip(np.where(real0 < 1.0, (fresnel_dielectric_average(ior) - real0) / (1.0 - real0), 1.0),
                                0.0, 1.0)
                f[:, sel] = col + (1.0 - col) * s
        return f

    def compensation(self, si: ShadingPoint, cos_o: np.ndarray) -> np.ndarray | None:
        """1 + F_ms (1 - E) / E (3, N) for the hits whose material compensates, 1 elsewhere; None
        if none does."""
        return self.compensation_terms(si, cos_o)[0]

    def compensation_terms(self, si: ShadingPoint, cos_o: np.ndarray):
        """(compensation, E(cos_o) (N,) of the albedo table): both None if no material compensates."""
        on = self.compensate.take(si.material)
        if not on.any():
            return None, None
        rough = self.table_roughness(si)
        e = albedo_tables.albedo(rough, np.clip(cos_o, 0.0, 1.0))
        e_avg = albedo_tables.average_albedo(rough)
        f_ss = self._fresnel_average(si)
        f_ms = f_ss * e_avg / (1.0 - f_ss * (1.0 - e_avg))
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = 1.0 + f_ms * np.where(e > 0.0, (1.0 - e) / e, 0.0)
        return np.where(on, scale, 1.0), e

    def _compensation_terms_at(self, si: ShadingPoint):
        return si.memo((self, "compensation"),
                       lambda at: self.compensation_terms(at, dot(at.wo, specular_normal_at(at))))

    def compensation_at(self, si: ShadingPoint) -> np.ndarray | None:
        """compensation at cos_o = dot(wo, n) (wo's local z), once per hit for the sample and the
        evals at the same hits (ShadingPoint.memo)."""
        return self._compensation_terms_at(si)[0]

    def albedo_at(self, si: ShadingPoint) -> np.ndarray | None:
        """E (N,) of the albedo table at the lobe's normal (clip(dot(wo, n), 0, 1)), as compensation_at
        reads it; None if no material compensates."""
        return self._compensation_terms_at(si)[1]

    def _frame_at(self, si: ShadingPoint):
        return si.memo((self, "frame"), self._frame)

    def _lobe(self, si, wo_l, wi_l, h, ax, ay, beckmann):
        """(D, Lambda(wo), Lambda(wi)) per hit, each distribution on its hits."""
        d, lo, li = np.empty(len(si)), np.empty(len(si)), np.empty(len(si))
        for dist, mask in ((GGX, ~beckmann), (BECKMANN, beckmann)):
            sel = np.flatnonzero(mask)
            if not len(sel):
                continue
            a, b = ax.take(sel), ay.take(sel)
            d[sel] = D[dist](h.take(sel, axis=1), a, b)
            lo[sel] = LAMBDA[dist](wo_l.take(sel, axis=1), a, b)
            li[sel] = LAMBDA[dist](wi_l.take(sel, axis=1), a, b)
        return d, lo, li

    # -- the protocol -------------------------------------------------------------------------
    def sample(self, si: ShadingPoint, u_lobe, u) -> BSDFSample:
        ax, ay, beckmann = self._alphas(si)
        x, y, n = self._frame_at(si)
        if self.compiled is not None and not beckmann.any():
            wi, cos_h, pdf, ratio = self.compiled.ggx_sample(si.wo, x, y, n, ax, ay, u[0], u[1])
            value = self._fresnel(si, cos_h) * ratio
            scale = self.compensation_at(si)
            if scale is not None:
                value = value * scale
            return BSDFSample(wi, np.nan_to_num(value), pdf, np.full(len(si), LOBE, dtype=np.int8))
        wo_l = to_local(si.wo, x, y, n)
        h = np.empty_like(wo_l)
        for dist, mask in ((GGX, ~beckmann), (BECKMANN, beckmann)):
            sel = np.flatnonzero(mask)
            if len(sel):
                h[:, sel] = SAMPLE_VNDF[dist](wo_l.take(sel, axis=1), ax.take(sel), ay.take(sel),
                                              u[0].take(sel), u[1].take(sel))
        cos_h = dot(wo_l, h)
        wi_l = 2.0 * cos_h * h - wo_l
        ok = (wo_l[2] > 0.0) & (wi_l[2] > 0.0)
        d, lo, li = self._lobe(si, wo_l, wi_l, h, ax, ay, beckmann)
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf = np.where(ok, d / (4.0 * wo_l[2] * (1.0 + lo)), 0.0)
            ratio = np.where(ok, (1.0 + lo) / (1.0 + lo + li), 0.0)          # G2 / G1(wo)
        value = self._fresnel(si, np.clip(cos_h, 0.0, 1.0)) * ratio
        scale = self.compensation_at(si)
        if scale is not None:
            value = value * scale
        wi = normalize(to_world(wi_l, x, y, n))
        return BSDFSample(wi, np.nan_to_num(value), np.nan_to_num(pdf), np.full(len(si), LOBE, dtype=np.int8))

    def _tinted_hits(self, si: ShadingPoint):
        """What the compiled eval of a lobe whose Fresnel is its colour reads per hit (C-contiguous):
        wo, the frame x, y, n, the alphas, the colour and the compensation (1 where none); None
        where a hit is Beckmann."""
        ax, ay, beckmann = self._alphas(si)
        if beckmann.any():
            return None
        x, y, n = self._frame_at(si)
        scale = self.compensation_at(si)
        rows = np.ascontiguousarray
        return SimpleNamespace(wo=rows(si.wo), x=rows(x), y=rows(y), n=rows(n), ax=rows(ax), ay=rows(ay),
                               colour=rows(si.color), comp=rows(np.ones((3, len(si))) if scale is None else scale))

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.compiled is not None and self.tinted:        # the Glossy BSDF: reads its hits by index
            hits, index = si.memo_at((self, "tinted"), self._tinted_hits)
            if hits is not None:
                return self.compiled.tinted_eval(hits, index, wi)
        ax, ay, beckmann = self._alphas(si)
        x, y, n = self._frame_at(si)
        if self.compiled is not None and not beckmann.any():
            cos, pdf, g = self.compiled.ggx_eval(si.wo, wi, x, y, n, ax, ay)
            f_cos = self._fresnel(si, cos) * g
            scale = self.compensation_at(si)
            return (f_cos if scale is None else f_cos * scale), pdf
        wo_l, wi_l = to_local(si.wo, x, y, n), to_local(wi, x, y, n)
        ok = (wo_l[2] > 0.0) & (wi_l[2] > 0.0)
        half = wo_l + wi_l
        length = np.sqrt(dot(half, half))
        h = half / np.where(length > 0.0, length, 1.0)
        d, lo, li = self._lobe(si, wo_l, wi_l, h, ax, ay, beckmann)
        with np.errstate(divide="ignore", invalid="ignore"):
            common = np.where(ok, d / (4.0 * wo_l[2]), 0.0)
            pdf = np.nan_to_num(common / (1.0 + lo))
            f_cos = self._fresnel(si, np.clip(dot(wo_l, h), 0.0, 1.0)) * np.nan_to_num(common / (1.0 + lo + li))
        scale = self.compensation_at(si)
        if scale is not None:
            f_cos = f_cos * scale
        return f_cos, pdf

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        return self.eval(si, wi)[1]
