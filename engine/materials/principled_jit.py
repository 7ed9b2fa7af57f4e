"""The Principled BSDF v2 (engine/materials/principled.py PrincipledV2: the metallic and specular GGX
lobes over the Lambertian diffuse, and over them the sheen and the coat) compiled with numba: its
eval and pdf as passes over the (hit, direction) pairs that read the per-hit values (frames, alphas,
Fresnel inputs, compensation, the sheen's LTC a and b, lobe weights and probabilities, computed once
per scatter group by NumPy, principled.py `_fused_hits`) by index, so a light sample's eval gathers
nothing, and its sample's lobe pick with the GGX directions as one pass over the hits.

The base's two microfacet lobes share their geometry (the same frame, alphas and half vector: both
are set up from the same material), so D and the Lambdas are computed once; the coat has its own
(its roughness, isotropic, on the same normal), one more GGX pass where a material is coated.  Every
number repeats the NumPy path's float64 operations in the same order (engine/materials/glossy.py
MicrofacetReflection.eval and sample with the GGX kernels of engine/materials/microfacet_jit.py,
fresnel_f82, fresnel_dielectric, sheen.py ltc_value, principled.py real_fresnel_s, _mixture and
_layered_mixture: sheen, coat, metal, specular, diffuse, each added to the running sum from 0,
oren_nayar.py's Lambert case) with only +, -, *, /, sqrt, cos and sin; the one power (the F82
Fresnel's (1 - cos)^5) and the directions that take NumPy's sin and cos (the diffuse picks' cosine
directions, the sheen's disk) stay NumPy, between the passes; so do the per-hit layer weights (the
coat tint's power), whose closure weights and lobe probabilities are then combined in one pass
(`layered_probabilities`).  The same bits as backend=numpy (tests/materials/test_principled_jit.py).
Imported only through engine/core/backend.py's choice (it imports numba)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from . import lambert_jit
from .microfacet_jit import PI, _clip01, _finite, eval_hit, sample_hit

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

INV_PI = 1.0 / np.pi
GLOSSY = 9                  # BSDFFlags.GLOSSY | REFLECTION (engine/materials/protocol.py)
DIFFUSE = 5                 # BSDFFlags.DIFFUSE | REFLECTION
MAX_FLOAT = np.finfo(np.float64).max


@jit
def _max_keep_nan(v):
    """np.maximum(v, 0.0) (NaN stays NaN; the sign of a zero never reaches the sums)."""
    if v != v:
        return v
    return v if v >= 0.0 else 0.0


@jit
def _fresnel_dielectric(cos, ior):
    """engine/materials/glossy.py fresnel_dielectric of one hit."""
    g2 = ior * ior - 1.0 + cos * cos
    if g2 < 0.0:
        return 1.0
    g = np.sqrt(g2)
    a = (g - cos) / (g + cos)
    b = (cos * (g + cos) - 1.0) / (cos * (g - cos) + 1.0)
    f = 0.5 * a * a * (1.0 + b * b)
    if f != f:
        return 1.0
    return _clip01(f)


@jit
def _geometry(index, wo, wi, x, y, n, ax, ay, on_a, on_b, cos_out, pdf_out, g_out):
    """GGX (cos, pdf, g) of each pair (hit index[k], wi[:, k]) where a lobe on_a or on_b is set up."""
    for k in range(index.shape[0]):
        j = index[k]
        if on_a[j] or on_b[j]:
            cos_out[k], pdf_out[k], g_out[k] = eval_hit(wo, wi, x, y, n, j, k, ax[j], ay[j])
        else:
            cos_out[k], pdf_out[k], g_out[k] = 0.0, 0.0, 0.0


@jit
def _layers(index, wi, sx, sy, sn, sheen_a, sheen_b, w_sheen, on_sheen, cos, pdf_g, g, w_coat, on_coat, coat_eta,
            comp_coat, prob, f_out, pdf_out):
    """f cos (3, K) and pdf (K,) of the layers over the base: the sheen (engine/materials/sheen.py
    ltc_value in its frame sx, sy, sn), then the coat (GGX, dielectric Fresnel of coat_eta, colour
    1), as principled.py _layered_mixture sums them (from 0)."""
    for k in range(index.shape[0]):
        j = index[k]
        f_r, f_g, f_b, pdf = 0.0, 0.0, 0.0, 0.0
        if on_sheen[j]:
            l0 = wi[0, k] * sx[0, j] + wi[1, k] * sx[1, j] + wi[2, k] * sx[2, j]
            l1 = wi[0, k] * sy[0, j] + wi[1, k] * sy[1, j] + wi[2, k] * sy[2, j]
            l2 = wi[0, k] * sn[0, j] + wi[1, k] * sn[1, j] + wi[2, k] * sn[2, j]
            a, b = sheen_a[j], sheen_b[j]
            t0, t1 = a * l0 + b * l2, a * l1
            ratio = a / (t0 * t0 + t1 * t1 + l2 * l2)
            d = _finite(_max_keep_nan(l2) / PI * (ratio * ratio))
            f_r = f_r + w_sheen[0, j] * d
            f_g = f_g + w_sheen[1, j] * d
            f_b = f_b + w_sheen[2, j] * d
            pdf = pdf + prob[1, j] * d
        if on_coat[j]:
            fg = _fresnel_dielectric(cos[k], coat_eta[j]) * g[k]
            f_r = f_r + w_coat[0, j] * (fg * comp_coat[0, j])
            f_g = f_g + w_coat[1, j] * (fg * comp_coat[1, j])
            f_b = f_b + w_coat[2, j] * (fg * comp_coat[2, j])
            pdf = pdf + prob[2, j] * pdf_g[k]
        f_out[0, k], f_out[1, k], f_out[2, k] = f_r, f_g, f_b
        pdf_out[k] = pdf


@jit
def _combine(index, wi, cos, pdf_g, g, s5, nd, w_metal, w_spec, w_diffuse, on_metal, on_spec, on_diffuse, prob, row,
             f0_metal, b_metal, comp_metal, spec_colour, eta, f0_spec, comp_spec, colour, f_out, pdf_out):
    """The base's metal, specular and diffuse (weights (3, N), probabilities prob[row:row + 3])
    added in that order to f cos (3, K) and pdf (K,) (zeros, or the layers over the base)."""
    for k in range(index.shape[0]):
        j = index[k]
        f_r, f_g, f_b, pdf = f_out[0, k], f_out[1, k], f_out[2, k], pdf_out[k]
        if on_metal[j]:
            c = cos[k]
            s = _clip01(1.0 - c)
            t5 = s5[k]
            gk = g[k]
            out = [0.0, 0.0, 0.0]
            for ch in range(3):
                f0 = f0_metal[ch, j]
                fr = _clip01(f0 + (1.0 - f0) * t5 - b_metal[ch, j] * c * t5 * s)
                out[ch] = w_metal[ch, j] * (fr * gk * comp_metal[ch, j])
            f_r, f_g, f_b = f_r + out[0], f_g + out[1], f_b + out[2]
            pdf = pdf + prob[row, j] * pdf_g[k]
        if on_spec[j]:
            f0 = f0_spec[j]
            s = (_fresnel_dielectric(cos[k], eta[j]) - f0) / (1.0 - f0)
            if s != s:
                s = 1.0
            s = _clip01(s)
            gk = g[k]
            out = [0.0, 0.0, 0.0]
            for ch in range(3):
                col = spec_colour[ch, j]
                out[ch] = w_spec[ch, j] * ((col + (1.0 - col) * s) * gk * comp_spec[ch, j])
            f_r, f_g, f_b = f_r + out[0], f_g + out[1], f_b + out[2]
            pdf = pdf + prob[row + 1, j] * pdf_g[k]
        if on_diffuse[j]:
            cos_d = wi[0, k] * nd[0, j] + wi[1, k] * nd[1, j] + wi[2, k] * nd[2, j]
            cos_i = _max_keep_nan(cos_d)
            pdf_d = cos_i * INV_PI
            f_r = f_r + w_diffuse[0, j] * (colour[0, j] * pdf_d)
            f_g = f_g + w_diffuse[1, j] * (colour[1, j] * pdf_d)
            f_b = f_b + w_diffuse[2, j] * (colour[2, j] * pdf_d)
            pdf = pdf + prob[row + 2, j] * pdf_d
        f_out[0, k], f_out[1, k], f_out[2, k] = f_r, f_g, f_b
        pdf_out[k] = pdf


@jit
def _pick(wo, x, y, n, ax, ay, prob, u_lobe, u1, u2, wi_out, flags_out):
    """The lobe pick (0 metal, 1 specular, 2 diffuse by the cdf of prob; diffuse where prob sums to
    0) and the GGX direction of the hits that picked a microfacet lobe; returns their count."""
    glossy = 0
    for i in range(wo.shape[1]):
        p0 = prob[0, i]
        c1 = p0 + prob[1, i]
        choice = (1 if u_lobe[i] >= p0 else 0) + (1 if u_lobe[i] >= c1 else 0)
        if not c1 + prob[2, i] > 0.0:
            choice = 2
        if choice < 2:
            d0, d1, d2, _, _, _ = sample_hit(wo, x, y, n, i, ax[i], ay[i], u1[i], u2[i])
            wi_out[0, i], wi_out[1, i], wi_out[2, i] = d0, d1, d2
            flags_out[i] = GLOSSY
            glossy += 1
        else:
            flags_out[i] = DIFFUSE
    return glossy


@jit
def _layered_pick(wo, x, y, n, ax, ay, cx, cy, cn, cax, cay, prob, u_lobe, u1, u2, wi_out, flags_out, choice_out,
                  failed_out, counts, pass_flags):
    """The lobe pick of principled.py _layered_sample (0 pass-through, 1 sheen, 2 coat, 3 metal,
    4 specular, 5 diffuse, 6 the transmission closure where prob has its row: u_lobe against the
    running sum of prob, as np.cumsum), the pass-through's direction -wo and flags pass_flags, and the GGX
    directions of the coat (its frame cx, cy, cn) and of the base's microfacet lobes; failed_out:
    where such a GGX sample's pdf is not positive (principled.py _sample_lobes' `failed`), False
    elsewhere; counts (7,): how many hits picked each lobe."""
    rows = prob.shape[0]
    counts[:] = 0
    for i in range(wo.shape[1]):
        c = 0.0
        choice = 0
        for r in range(rows - 1):
            c = c + prob[r, i] if r > 0 else prob[r, i]
            if u_lobe[i] >= c:
                choice += 1
        choice_out[i] = choice
        counts[choice] += 1
        failed_out[i] = False
        if choice == 2:
            d0, d1, d2, _, pdf, _ = sample_hit(wo, cx, cy, cn, i, cax[i], cay[i], u1[i], u2[i])
        elif choice == 3 or choice == 4:
            d0, d1, d2, _, pdf, _ = sample_hit(wo, x, y, n, i, ax[i], ay[i], u1[i], u2[i])
        elif choice == 0:
            wi_out[0, i], wi_out[1, i], wi_out[2, i] = -wo[0, i], -wo[1, i], -wo[2, i]
            flags_out[i] = pass_flags
            continue
        else:
            flags_out[i] = DIFFUSE
            continue
        wi_out[0, i], wi_out[1, i], wi_out[2, i] = d0, d1, d2
        flags_out[i] = GLOSSY
        failed_out[i] = pdf <= 0.0


@jit
def _to_finite(v):
    """np.nan_to_num of one float64: NaN 0, +-inf the largest finite float of that sign."""
    if v != v:
        return 0.0
    if v > MAX_FLOAT:
        return MAX_FLOAT
    if v < -MAX_FLOAT:
        return -MAX_FLOAT
    return v


@jit
def _values(f_cos, pdf, choice, p_through, w_through, failed, value):
    """The throughput weights of principled.py's sample from the mixture's f cos (3, N) and pdf (N,)
    (in place): f cos / pdf where pdf > 0, else 0; at the pass-through picks (choice 0; `choice`
    empty: none) w_through / p_through where p_through > 0, else 0, and pdf p_through; 0 and pdf 0
    where `failed` (empty: nowhere); then np.nan_to_num."""
    layered = choice.shape[0] > 0
    checked = failed.shape[0] > 0
    for i in range(pdf.shape[0]):
        if layered and choice[i] == 0:
            p = p_through[i]
            v = w_through[i] / p if p > 0.0 else 0.0
            value[0, i], value[1, i], value[2, i] = v, v, v
            pdf[i] = p
        else:
            p = pdf[i]
            for c in range(3):
                value[c, i] = f_cos[c, i] / p if p > 0.0 else 0.0
        if checked and failed[i]:
            value[0, i], value[1, i], value[2, i] = 0.0, 0.0, 0.0
            pdf[i] = 0.0
        for c in range(3):
            value[c, i] = _to_finite(value[c, i])


def sample_values(f_cos, pdf, choice=None, p_through=None, w_through=None, failed=None):
    """(value (3, N), pdf (N,)) of a sample from its mixture's f_cos and pdf (pdf changed in place):
    `_values`; choice, p_through, w_through (N,): the layered pick and its pass-through's
    probability and weight, failed (N,) bool: the samples their lobe rejected (None: none)."""
    value = np.empty_like(f_cos)
    none = np.empty(0)
    _values(f_cos, pdf, none.astype(np.int64) if choice is None else choice, none if p_through is None else p_through,
            none if w_through is None else np.ascontiguousarray(w_through, dtype=np.float64),
            none.astype(np.bool_) if failed is None else failed, value)
    return value, pdf


def diffuse_directions(idx, u1, u2, n, wi, failed=None):
    """The diffuse picks idx's cosine-weighted directions about n[:, idx] written into wi (3, N), as
    principled.py's NumPy path draws them (warps.cosine_directions, by engine/materials/lambert_jit.py
    with NumPy's float32 cos and sin), and where their Lambertian pdf is not positive into failed."""
    pdf = lambert_jit.sample_at(idx, u1, u2, n, wi)
    if failed is not None:
        failed[idx] = pdf <= 0.0


@jit
def _nan_max(a, b):
    """np.maximum of two floats: a where a >= b or a is NaN, else b (NaN where b is)."""
    if a != a or a >= b:
        return a
    return b


@jit
def _table(flat, row, mu, points):
    """principled.py _read of one hit: the table row `row` (of `points` points over sqrt(mu), flat)
    at mu clipped to [0, 1], linear between its points (NaN where mu is NaN, where NumPy's gather
    raises)."""
    x = np.sqrt(_clip01(mu)) * (points - 1)
    if x != x:
        return x
    j = min(int(x), points - 1)
    k = min(j + 1, points - 1)
    t = x - j
    return (1.0 - t) * flat[row * points + j] + t * flat[row * points + k]


@jit
def _lobe_weights(mat, metallic, wo, ns, s_metal, s_spec, s_hits, metal_colour, spec_colour, dark_metal, dark_spec,
                  has_specular, transmission, colour, glossy_off, cutoff, points, normalise, w_out, sample_out):
    """principled.py lobe_weights and layer_albedos per hit: the albedo estimates darkening x
    (F0 + (1 - F0) s(mu)) of the metal and the specular lobe at mu = wo . ns (s from the tables, or
    the hits' own s_hits (2, N) where not empty: textured roughness; dark_* empty: no compensation,
    a factor 1.0), the closure weights into w_out (3, N) and the sample weights (or, where
    `normalise`, the probabilities) into sample_out (3, N)."""
    dark_m, dark_s = dark_metal.shape[0] > 0, dark_spec.shape[0] > 0
    own_s = s_hits.shape[0] > 0
    transmits, off = transmission.shape[0] > 0, glossy_off.shape[0] > 0
    a_m = np.empty(3)
    a_s = np.empty(3)
    for i in range(mat.shape[0]):
        row = mat[i]
        spec = has_specular[row]
        if own_s:
            sm, ss = s_hits[0, i], s_hits[1, i]
        else:
            mu = wo[0, i] * ns[0, i] + wo[1, i] * ns[1, i] + wo[2, i] * ns[2, i]
            sm = _table(s_metal, row, mu, points)
            ss = _table(s_spec, row, mu, points) if spec else 0.0
        for c in range(3):
            mc = metal_colour[c, i]
            a_m[c] = (dark_metal[c, i] if dark_m else 1.0) * (mc + (1.0 - mc) * sm)
            sc = spec_colour[c, i]
            a_s[c] = (dark_spec[c, i] if dark_s else 1.0) * (sc + (1.0 - sc) * ss) if spec else 0.0
        m = _clip01(metallic[i])
        w_metal = m if m > cutoff else 0.0
        w_rest = 1.0 - m
        w_rest = w_rest if w_rest > cutoff else 0.0
        if transmits:
            w_rest = w_rest * (1.0 - transmission[row])
        w_spec = w_rest if spec else 0.0
        w_diffuse = w_rest * _clip01(1.0 - _nan_max(_nan_max(a_s[0], a_s[1]), a_s[2]))
        if off and glossy_off[i]:
            w_metal, w_spec, w_diffuse = 0.0, 0.0, w_rest
        w_out[0, i], w_out[1, i], w_out[2, i] = w_metal, w_spec, w_diffuse
        s0 = w_metal * ((a_m[0] + a_m[1] + a_m[2]) / 3.0)
        s1 = w_spec * ((a_s[0] + a_s[1] + a_s[2]) / 3.0)
        s2 = w_diffuse * ((abs(colour[0, i]) + abs(colour[1, i]) + abs(colour[2, i])) / 3.0)
        if normalise:
            total = s0 + s1 + s2
            if total > 0.0:
                s0, s1, s2 = s0 / total, s1 / total, s2 / total
            else:
                s0, s1, s2 = 0.0, 0.0, 0.0
        sample_out[0, i], sample_out[1, i], sample_out[2, i] = s0, s1, s2


def lobe_weights(mat, metallic, wo, ns, s_metal, s_spec, s_hits, metal_colour, spec_colour, dark_metal, dark_spec,
                 has_specular, transmission, colour, glossy_off, cutoff, normalise):
    """((w_metal, w_specular, w_diffuse) (N,) each, sample weights or probabilities (3, N)) of
    principled.py lobe_weights: mat (N,) material ids, metallic (N,) the hits' metallic, wo and ns
    (3, N) the view and the lobes' normal, s_metal and s_spec (M, points) the s(mu) tables, s_hits
    (2, N) the hits' s of the metal and the specular lobe or None (read from the tables), metal_colour and spec_colour (3, N) the lobes' F0, dark_metal and
    dark_spec (3, N) their darkening or None, has_specular (M,), transmission (M,) or None (no
    transmission closure), colour (3, N), glossy_off (N,) or None, normalise: probabilities."""
    count = len(mat)
    w, sample = np.empty((3, count)), np.empty((3, count))
    rows = np.ascontiguousarray
    none = np.empty((0, 0))
    _lobe_weights(rows(mat, dtype=np.int64), rows(metallic, dtype=np.float64), rows(wo), rows(ns), rows(s_metal).ravel(),
                  rows(s_spec).ravel(), none if s_hits is None else rows(s_hits), rows(metal_colour), rows(spec_colour),
                  none if dark_metal is None else rows(dark_metal), none if dark_spec is None else rows(dark_spec),
                  has_specular, np.empty(0) if transmission is None else transmission, rows(colour),
                  np.empty(0, dtype=np.bool_) if glossy_off is None else glossy_off, cutoff, s_metal.shape[1],
                  normalise, w, sample)
    return (w[0], w[1], w[2]), sample


@jit
def _layered_probabilities(sheen, coat, coat_albedo, base, base_sample, w_metal, w_spec, w_diffuse, w_glass,
                           glass_weight, through, weights_out, prob_out):
    """principled.py _layered_lobes after its layer and lobe weights: the base lobes' closure weights
    (3, N) each into weights_out (metal, specular, diffuse, and the glass where w_glass has hits),
    the probabilities (6 or 7, N) of pass-through, sheen, coat, metal, specular, diffuse (, glass):
    NumPy's channel means (c0 + c1 + c2) / 3, its row sums in row order, np.where's choices."""
    rows = prob_out.shape[0] - 1
    sample = np.empty(6)
    for i in range(base.shape[1]):
        mean_base = (base[0, i] + base[1, i] + base[2, i]) / 3.0
        sample[0] = (sheen[0, i] + sheen[1, i] + sheen[2, i]) / 3.0
        sample[1] = (coat[0, i] + coat[1, i] + coat[2, i]) / 3.0 * coat_albedo[i]
        sample[2] = base_sample[0, i] * mean_base
        sample[3] = base_sample[1, i] * mean_base
        sample[4] = base_sample[2, i] * mean_base
        for c in range(3):
            weights_out[0, c, i] = w_metal[i] * base[c, i]
            weights_out[1, c, i] = w_spec[i] * base[c, i]
            weights_out[2, c, i] = w_diffuse[i] * base[c, i]
        if rows == 6:
            sample[5] = w_glass[i] * mean_base * glass_weight[i]
            for c in range(3):
                weights_out[3, c, i] = w_glass[i] * base[c, i]
        total = sample[0]
        for r in range(1, rows):
            total = total + sample[r]
        opaque = 1.0 - through[i] if total > 0.0 else 0.0
        prob_out[0, i] = 1.0 - opaque
        for r in range(rows):
            prob_out[r + 1, i] = opaque * sample[r] / total if total > 0.0 else 0.0


def layered_probabilities(layers, w_metal, w_spec, w_diffuse, base_sample, w_glass=None, glass_weight=None):
    """(closure weights [sheen, coat, metal, specular, diffuse (, glass)] (3, N) each, probabilities
    (6 or 7, N)) of principled.py _layered_lobes from its layers (layer_weights) and the base's lobe
    weights and sample weights (lobe_weights(sample_total=True)); w_glass, glass_weight (N,): the
    transmission closure's weight and albedo estimate where any material transmits."""
    count = layers.base.shape[1]
    rows = np.ascontiguousarray
    glass = w_glass is not None
    out = np.empty((4 if glass else 3, 3, count))
    prob = np.empty((7 if glass else 6, count))
    none = np.empty(0)
    _layered_probabilities(rows(layers.sheen), rows(layers.coat), rows(layers.coat_albedo, dtype=np.float64),
                           rows(layers.base), rows(base_sample), rows(w_metal, dtype=np.float64),
                           rows(w_spec, dtype=np.float64), rows(w_diffuse, dtype=np.float64),
                           rows(w_glass) if glass else none, rows(glass_weight) if glass else none,
                           rows(layers.through, dtype=np.float64), out, prob)
    return [layers.sheen, layers.coat, *out], prob


def base_eval(hits, index, wi):
    """(f cos (3, K), pdf (K,)) of the lobes at the pairs (hit index[k], wi[:, k]): the sheen and the
    coat where hits.layered, then the base; hits: the per-hit arrays of principled.py `_fused_hits`,
    index None for the hits themselves."""
    count = wi.shape[1]
    if index is None:
        index = np.arange(count)
    index = np.ascontiguousarray(index, dtype=np.int64)
    wi = np.ascontiguousarray(wi, dtype=np.float64)
    f_cos, pdf = np.zeros((3, count)), np.zeros(count)
    cos, pdf_g, g = np.empty(count), np.empty(count), np.empty(count)
    if hits.layered:
        c = hits.coat
        _geometry(index, hits.wo, wi, c.x, c.y, c.n, c.ax, c.ay, c.on, c.on, cos, pdf_g, g)
        s = hits.sheen
        _layers(index, wi, s.x, s.y, s.n, s.a, s.b, s.w, s.on, cos, pdf_g, g, c.w, c.on, c.eta, c.comp, hits.prob,
                f_cos, pdf)
    _geometry(index, hits.wo, wi, hits.x, hits.y, hits.n, hits.ax, hits.ay, hits.on_metal, hits.on_spec,
              cos, pdf_g, g)
    s5 = np.clip(1.0 - cos, 0.0, 1.0) ** 5 if hits.any_metal else cos     # fresnel_f82's power, NumPy's
    _combine(index, wi, cos, pdf_g, g, s5, hits.nd, hits.w_metal, hits.w_spec, hits.w_diffuse, hits.on_metal,
             hits.on_spec, hits.on_diffuse, hits.prob, hits.base_row, hits.f0_metal, hits.b_metal, hits.comp_metal,
             hits.spec_colour, hits.eta, hits.f0_spec, hits.comp_spec, hits.colour, f_cos, pdf)
    return f_cos, pdf


def base_pick(hits, u_lobe, u1, u2):
    """(wi (3, N) with the GGX directions of the glossy picks, flags (N,) int8, the diffuse picks'
    indices) at the hits themselves."""
    count = hits.wo.shape[1]
    wi = np.empty((3, count))
    flags = np.empty(count, dtype=np.int8)
    u_lobe, u1, u2 = (np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=np.float64), (count,)))
                      for a in (u_lobe, u1, u2))
    glossy = _pick(hits.wo, hits.x, hits.y, hits.n, hits.ax, hits.ay, hits.prob, u_lobe, u1, u2, wi, flags)
    diffuse = np.flatnonzero(flags == DIFFUSE) if glossy < count else np.empty(0, dtype=np.int64)
    return wi, flags, diffuse


def layered_pick(hits, u_lobe, u1, u2, pass_flags):
    """(wi (3, N) with the directions of the pass-through (-wo), coat, metal and specular picks, flags
    (N,) int8 (pass_flags at the pass-through, principled.py PASS_LOBE; glossy; the rest diffuse:
    principled.py sets the sheen's and the transmission's), the choices (N,), where a GGX pick's pdf
    is not positive (N,) bool, how many hits picked each lobe (7,)) at the hits themselves
    (hits.layered)."""
    count = hits.wo.shape[1]
    wi = np.empty((3, count))
    flags = np.empty(count, dtype=np.int8)
    choice = np.empty(count, dtype=np.int64)
    failed = np.empty(count, dtype=np.bool_)
    counts = np.empty(7, dtype=np.int64)
    u_lobe, u1, u2 = (np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=np.float64), (count,)))
                      for a in (u_lobe, u1, u2))
    c = hits.coat
    _layered_pick(hits.wo, hits.x, hits.y, hits.n, hits.ax, hits.ay, c.x, c.y, c.n, c.ax, c.ay, hits.prob, u_lobe,
                  u1, u2, wi, flags, choice, failed, counts, int(pass_flags))
    return wi, flags, choice, failed, counts


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    from types import SimpleNamespace
    frame = np.eye(3)[:, :, None].repeat(2, axis=2)
    wo = np.ascontiguousarray(np.array([[0.1, 0.0], [0.2, 0.0], [0.97, 1.0]]))
    ones = np.ones((3, 2))
    on = np.array([True, True])
    hits = SimpleNamespace(wo=wo, x=frame[0].copy(), y=frame[1].copy(), n=frame[2].copy(), nd=frame[2].copy(),
                           ax=np.array([0.25, 0.5]), ay=np.array([0.25, 0.5]), w_metal=ones * [1.0, 0.0],
                           w_spec=ones * [0.0, 1.0], w_diffuse=ones * [0.0, 0.5], on_metal=np.array([True, False]),
                           on_spec=np.array([False, True]), on_diffuse=np.array([False, True]),
                           prob=np.ascontiguousarray(np.array([[1.0, 0.0], [0.0, 0.5], [0.0, 0.5]])), base_row=0,
                           f0_metal=ones * 0.5, b_metal=ones * 0.1, comp_metal=ones, spec_colour=ones * 0.04,
                           eta=np.array([1.5, 1.5]), f0_spec=np.array([0.04, 0.04]), comp_spec=ones, colour=ones * 0.8,
                           any_metal=True, layered=False)
    base_eval(hits, None, wo[::-1].copy())
    base_eval(hits, np.array([1, 0]), wo.copy())
    base_pick(hits, np.array([0.3, 0.6]), np.array([0.3, 0.6]), np.array([0.2, 0.9]))
    hits.layered, hits.base_row = True, 3
    hits.prob = np.ascontiguousarray(np.vstack([np.zeros((3, 2)), hits.prob]))
    hits.coat = SimpleNamespace(x=hits.x, y=hits.y, n=hits.n, ax=hits.ax, ay=hits.ay, w=ones * 0.5, on=on,
                                eta=np.array([1.5, 1.5]), comp=ones)
    hits.sheen = SimpleNamespace(x=hits.x, y=hits.y, n=hits.n, a=np.array([0.5, 0.5]), b=np.array([0.1, 0.1]),
                                 w=ones * 0.5, on=on)
    base_eval(hits, None, wo[::-1].copy())
    base_eval(hits, np.array([1, 0]), wo.copy())
    wi, _, choice, failed, _ = layered_pick(hits, np.array([0.3, 0.9]), np.array([0.3, 0.6]), np.array([0.2, 0.9]), 50)
    f_cos, pdf = base_eval(hits, None, wi)
    sample_values(f_cos, pdf, choice, hits.prob[0], np.array([0.0, 0.5]), failed)
    sample_values(f_cos, pdf)
    diffuse_directions(np.array([1]), np.array([0.3, 0.6]), np.array([0.2, 0.9]), hits.n, wi, failed)
    for dark, off in ((None, None), (ones, np.array([True, False]))):
        for normalise in (False, True):
            lobe_weights(np.array([0, 1]), np.array([0.5, 1.0]), wo, frame[2].copy(), ones * 0.5, ones * 0.25,
                         None if dark is None else ones[:2] * 0.5, ones * 0.9, ones * 0.04, dark, dark, np.array([True, False]),
                         None if dark is None else np.array([0.0, 0.5]), ones, off, 1e-5, normalise)
    layers = SimpleNamespace(sheen=ones * 0.1, coat=ones * 0.2, coat_albedo=np.array([0.1, 0.2]), base=ones * 0.5,
                             through=np.array([0.0, 0.5]))
    w = np.array([0.5, 0.25])
    layered_probabilities(layers, w, w, w, ones * 0.3)
    layered_probabilities(layers, w, w, w, ones * 0.3, w, np.array([1.0, 0.9]))
