"""The Principled BSDF v1 (Blender 3.x; engine/materials/principled_v1.py PrincipledV1) compiled with
numba for materials without clearcoat and transmission: the diffuse (Burley), sheen and specular
(GGX, interpolated Fresnel, compensation) closures' eval and pdf as one pass over the (hit,
direction) pairs that reads the per-hit values (frame, alphas, Fresnel inputs, compensation, closure
weights and probabilities, computed once per scatter group by NumPy) by index, and the closure pick
with the specular lobe's GGX direction as one pass over the hits.  The alphas and the compensation
are PrincipledV1.inputs', already raised by Filter Glossy (ShadingPoint.alpha_floor) where it is on.

Every number repeats the NumPy path's float64 operations in the same order (principled_v1.py
_mixture, _diffuse, _sheen, _specular, schlick_weight, burley_diffuse; principled_v1_glass.py
interpolated_fresnel; engine/materials/microfacet.py ggx_d, ggx_lambda, ggx_sample_vndf through
engine/materials/microfacet_jit.py) with only +, -, *, /, sqrt, cos and sin; the cosine directions
of the diffuse and sheen picks (float32 sin and cos) stay NumPy.  The same bits as backend=numpy
(tests/materials/test_principled_v1_jit.py).  Imported only through engine/core/backend.py's choice
(it imports numba)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from .microfacet_jit import _clip01, _d, _finite, _lambda, sample_hit
from .principled_jit import _fresnel_dielectric, _max_keep_nan

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

PI = np.pi


@jit
def _schlick(cos):
    """schlick_weight: (1 - cos)^5 as four products, cos clamped."""
    m = _clip01(1.0 - cos)
    return m * m * m * m * m


@jit
def _normalized(a0, a1, a2):
    length = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    return a0 / length, a1 / length, a2 / length


@jit
def _eval(index, wo, wi, x, y, n, ax, ay, multi, roughness, eta, f0, cspec0, comp, w_diffuse, w_sheen, w_spec,
          prob, f_out, pdf_out):
    for k in range(index.shape[0]):
        j = index[k]
        o0 = wo[0, j] * x[0, j] + wo[1, j] * x[1, j] + wo[2, j] * x[2, j]
        o1 = wo[0, j] * y[0, j] + wo[1, j] * y[1, j] + wo[2, j] * y[2, j]
        o2 = wo[0, j] * n[0, j] + wo[1, j] * n[1, j] + wo[2, j] * n[2, j]
        i0 = wi[0, k] * x[0, j] + wi[1, k] * x[1, j] + wi[2, k] * x[2, j]
        i1 = wi[0, k] * y[0, j] + wi[1, k] * y[1, j] + wi[2, k] * y[2, j]
        i2 = wi[0, k] * n[0, j] + wi[1, k] * n[1, j] + wi[2, k] * n[2, j]
        f_r, f_g, f_b, pdf = 0.0, 0.0, 0.0, 0.0
        pdf_cos = _max_keep_nan(i2) / PI
        if max(w_diffuse[0, j], w_diffuse[1, j], w_diffuse[2, j]) > 0.0:        # Burley
            fo, fi = _schlick(o2), _schlick(i2)
            rr = roughness[j] * ((o0 * i0 + o1 * i1 + o2 * i2) + 1.0)
            fb = (1.0 - 0.5 * fo) * (1.0 - 0.5 * fi) + rr * (fi + fo + fi * fo * (rr - 1.0))
            fl = i2 / PI * fb if i2 > 0.0 else 0.0
            f_r, f_g, f_b = f_r + w_diffuse[0, j] * fl, f_g + w_diffuse[1, j] * fl, f_b + w_diffuse[2, j] * fl
            pdf = pdf + prob[0, j] * pdf_cos
        if max(w_sheen[0, j], w_sheen[1, j], w_sheen[2, j]) > 0.0:
            h0, h1, h2 = _normalized(o0 + i0, o1 + i1, o2 + i2)
            fl = _schlick(i0 * h0 + i1 * h1 + i2 * h2) * i2 if (i2 > 0.0 and o2 >= 0.0) else 0.0
            f_r, f_g, f_b = f_r + w_sheen[0, j] * fl, f_g + w_sheen[1, j] * fl, f_b + w_sheen[2, j] * fl
            pdf = pdf + prob[1, j] * pdf_cos
        if max(w_spec[0, j], w_spec[1, j], w_spec[2, j]) > 0.0:
            a_x, a_y = ax[j], ay[j]
            h0, h1, h2 = _normalized(o0 + i0, o1 + i1, o2 + i2)
            lo, li = _lambda(o0, o1, o2, a_x, a_y), _lambda(i0, i1, i2, a_x, a_y)
            common = _d(h0, h1, h2, a_x, a_y) / (4.0 * o2) if (o2 > 0.0 and i2 > 0.0) else 0.0
            g = 1.0 / (1.0 + lo + li) if multi[j] else 1.0 / ((1.0 + lo) * (1.0 + li))
            pl = _finite(common / (1.0 + lo))
            fl = _finite(common * g)
            e, f0j = eta[j], f0[j]
            if f0j < 1.0:
                s = (_fresnel_dielectric(_clip01(i0 * h0 + i1 * h1 + i2 * h2), e) - f0j) / (1.0 - f0j)
            else:
                s = 1.0
            out = [0.0, 0.0, 0.0]
            for ch in range(3):
                out[ch] = w_spec[ch, j] * ((cspec0[ch, j] * (1.0 - s) + s) * fl * comp[ch, j])
            f_r, f_g, f_b = f_r + out[0], f_g + out[1], f_b + out[2]
            pdf = pdf + prob[2, j] * pl
        f_out[0, k], f_out[1, k], f_out[2, k] = f_r, f_g, f_b
        pdf_out[k] = pdf


@jit
def _pick(wo, x, y, n, ax, ay, prob, u_lobe, u1, u2, wi_out, choice_out):
    """The closure pick by the cdf of prob (0 where the probabilities sum to 0: diffuse, sheen,
    specular, clearcoat) and the GGX direction of the hits that picked the specular closure."""
    for i in range(wo.shape[1]):
        c0 = prob[0, i]
        c1 = c0 + prob[1, i]
        c2 = c1 + prob[2, i]
        u = u_lobe[i]
        choice = (1 if u >= c0 else 0) + (1 if u >= c1 else 0) + (1 if u >= c2 else 0)
        if not c2 + prob[3, i] > 0.0:
            choice = 0
        if choice == 2:
            d0, d1, d2, _, _, _ = sample_hit(wo, x, y, n, i, ax[i], ay[i], u1[i], u2[i])
            wi_out[0, i], wi_out[1, i], wi_out[2, i] = d0, d1, d2
        choice_out[i] = choice


def closures_eval(hits, index, wi):
    """(f cos (3, K), pdf (K,)) at the pairs (hit index[k], wi[:, k]); hits: principled_v1.py
    `_fused_hits`, index None for the hits themselves."""
    count = wi.shape[1]
    index = np.arange(count) if index is None else np.ascontiguousarray(index, dtype=np.int64)
    f_cos, pdf = np.empty((3, count)), np.empty(count)
    _eval(index, hits.wo, np.ascontiguousarray(wi, dtype=np.float64), hits.x, hits.y, hits.n, hits.ax, hits.ay,
          hits.multi, hits.roughness, hits.eta, hits.f0, hits.cspec0, hits.comp, hits.w_diffuse, hits.w_sheen,
          hits.w_spec, hits.prob, f_cos, pdf)
    return f_cos, pdf


def closures_pick(hits, u_lobe, u1, u2):
    """(wi (3, N) with the specular picks' directions, the closure picked (N,) int8) at the hits
    themselves."""
    count = hits.wo.shape[1]
    wi = np.empty((3, count))
    choice = np.empty(count, dtype=np.int8)
    u_lobe, u1, u2 = (np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=np.float64), (count,)))
                      for a in (u_lobe, u1, u2))
    _pick(hits.wo, hits.x, hits.y, hits.n, hits.ax, hits.ay, hits.prob, u_lobe, u1, u2, wi, choice)
    return wi, choice


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    from types import SimpleNamespace
    frame = np.eye(3)[:, :, None].repeat(2, axis=2)
    wo = np.ascontiguousarray(np.array([[0.1, 0.0], [0.2, 0.0], [0.97, 1.0]]))
    ones = np.ones((3, 2))
    hits = SimpleNamespace(wo=wo, x=frame[0].copy(), y=frame[1].copy(), n=frame[2].copy(),
                           ax=np.array([0.25, 0.5]), ay=np.array([0.25, 0.5]), multi=np.array([True, False]),
                           roughness=np.array([0.5, 0.7]), eta=np.array([1.5, 1.5]), f0=np.array([0.04, 0.04]),
                           cspec0=ones * 0.04, comp=ones, w_diffuse=ones * 0.5, w_sheen=ones * 0.1, w_spec=ones,
                           prob=np.ascontiguousarray(np.array([[0.4, 0.4], [0.1, 0.1], [0.5, 0.5], [0.0, 0.0]])))
    closures_eval(hits, None, wo[::-1].copy())
    closures_eval(hits, np.array([1, 0]), wo.copy())
    closures_pick(hits, np.array([0.3, 0.6]), np.array([0.3, 0.6]), np.array([0.2, 0.9]))
