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
coat tint's power), which the base's lobe weights then combine into the closure weights and lobe
probabilities in the same pass (`layered_lobes`).  The metal's F82 b is made per pair from its F0
and the material's edge tint (glossy.py f82_b's operations), not read from a per-hit array.  The
same bits as backend=numpy (tests/materials/test_principled_jit.py).  Imported only through
engine/core/backend.py's choice (it imports numba)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from . import lambert_jit
from .glossy import F82_POW5, F82_SCALE
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
def _scale(comp, ch, j):
    """The compensation comp[ch, j], or 1.0 where comp is empty (no material compensates: NumPy's
    lobe multiplies by nothing, and x * 1.0 is x)."""
    return comp[ch, j] if comp.shape[0] > 0 else 1.0


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
    1, compensation comp_coat or, where empty, 1), as principled.py _layered_mixture sums them (from 0)."""
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
            f_r = f_r + w_coat[0, j] * (fg * _scale(comp_coat, 0, j))
            f_g = f_g + w_coat[1, j] * (fg * _scale(comp_coat, 1, j))
            f_b = f_b + w_coat[2, j] * (fg * _scale(comp_coat, 2, j))
            pdf = pdf + prob[2, j] * pdf_g[k]
        f_out[0, k], f_out[1, k], f_out[2, k] = f_r, f_g, f_b
        pdf_out[k] = pdf


@jit
def _f82(c, s, t5, f0, tint):
    """engine/materials/glossy.py fresnel_f82 of one channel at cos c (s = clip(1 - c), t5 = s^5,
    NumPy's power) with F0 f0 and its b = f82_b(f0, tint) (tint clipped to [0, 1])."""
    b = (f0 + (1.0 - f0) * F82_POW5) * F82_SCALE * (1.0 - tint)
    return _clip01(f0 + (1.0 - f0) * t5 - b * c * t5 * s)


@jit
def _combine(index, wi, cos, pdf_g, g, s5, nd, w_metal, w_spec, w_diffuse, on_metal, on_spec, on_diffuse, prob, row,
             mat, f0_metal, tint_metal, comp_metal, spec_colour, eta, f0_spec, comp_spec, colour, f_out, pdf_out):
    """The base's metal, specular and diffuse (weights (3, N), probabilities prob[row:row + 3])
    added in that order to f cos (3, K) and pdf (K,) (zeros, or the layers over the base); the metal's
    F82 b from its F0 and its material's clipped tint tint_metal (3, M); comp_* (3, N), or empty: 1."""
    for k in range(index.shape[0]):
        j = index[k]
        f_r, f_g, f_b, pdf = f_out[0, k], f_out[1, k], f_out[2, k], pdf_out[k]
        if on_metal[j]:
            c = cos[k]
            s = _clip01(1.0 - c)
            t5 = s5[k]
            gk = g[k]
            m = mat[j]
            fr = _f82(c, s, t5, f0_metal[0, j], tint_metal[0, m])
            f_r = f_r + w_metal[0, j] * (fr * gk * _scale(comp_metal, 0, j))
            fr = _f82(c, s, t5, f0_metal[1, j], tint_metal[1, m])
            f_g = f_g + w_metal[1, j] * (fr * gk * _scale(comp_metal, 1, j))
            fr = _f82(c, s, t5, f0_metal[2, j], tint_metal[2, m])
            f_b = f_b + w_metal[2, j] * (fr * gk * _scale(comp_metal, 2, j))
            pdf = pdf + prob[row, j] * pdf_g[k]
        if on_spec[j]:
            f0 = f0_spec[j]
            s = (_fresnel_dielectric(cos[k], eta[j]) - f0) / (1.0 - f0)
            if s != s:
                s = 1.0
            s = _clip01(s)
            gk = g[k]
            c0, c1, c2 = spec_colour[0, j], spec_colour[1, j], spec_colour[2, j]
            f_r = f_r + w_spec[0, j] * ((c0 + (1.0 - c0) * s) * gk * _scale(comp_spec, 0, j))
            f_g = f_g + w_spec[1, j] * ((c1 + (1.0 - c1) * s) * gk * _scale(comp_spec, 1, j))
            f_b = f_b + w_spec[2, j] * ((c2 + (1.0 - c2) * s) * gk * _scale(comp_spec, 2, j))
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
                  has_specular, transmission, colour, glossy_off, cutoff, points, normalise, w_out, sample_out,
                  sheen, coat, coat_albedo, base, alpha, through, w_glass, glass_weight, weights_out, prob_out):
    """principled.py lobe_weights and layer_albedos per hit: the albedo estimates darkening x
    (F0 + (1 - F0) s(mu)) of the metal and the specular lobe at mu = wo . ns (s from the tables, or
    the hits' own s_hits (2, N) where not empty: textured roughness; dark_* empty: no compensation,
    a factor 1.0), the closure weights into w_out (3, N) and the sample weights (or, where
    `normalise`, the probabilities) into sample_out (3, N).  Where prob_out is not empty, instead
    principled.py _layered_lobes on them (the base's sample weights, not normalised): the base lobes'
    closure weights (3, N) each into weights_out (metal, specular, diffuse, and the glass where w_glass
    has hits), the probabilities (6 or 7, N) of pass-through, sheen, coat, metal, specular, diffuse
    (, glass) into prob_out: NumPy's channel means (c0 + c1 + c2) / 3, its row sums in row order,
    np.where's choices; sheen, coat, base empty: no sheen nor coat at these hits (layer_weights'
    zeros; the base weight W is alpha in every channel)."""
    dark_m, dark_s = dark_metal.shape[0] > 0, dark_spec.shape[0] > 0
    own_s = s_hits.shape[0] > 0
    transmits, off = transmission.shape[0] > 0, glossy_off.shape[0] > 0
    layered, bare = prob_out.shape[0] > 0, sheen.shape[0] == 0
    n_sample = prob_out.shape[0] - 1      # the sample weights' rows: 5, or 6 with the glass
    a_m = np.empty(3)
    a_s = np.empty(3)
    sample = np.empty(6)
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
        s0 = w_metal * ((a_m[0] + a_m[1] + a_m[2]) / 3.0)
        s1 = w_spec * ((a_s[0] + a_s[1] + a_s[2]) / 3.0)
        s2 = w_diffuse * ((abs(colour[0, i]) + abs(colour[1, i]) + abs(colour[2, i])) / 3.0)
        if not layered:
            w_out[0, i], w_out[1, i], w_out[2, i] = w_metal, w_spec, w_diffuse
            if normalise:
                total = s0 + s1 + s2
                if total > 0.0:
                    s0, s1, s2 = s0 / total, s1 / total, s2 / total
                else:
                    s0, s1, s2 = 0.0, 0.0, 0.0
            sample_out[0, i], sample_out[1, i], sample_out[2, i] = s0, s1, s2
            continue
        if bare:
            b0 = b1 = b2 = alpha[i]
            sample[0], sample[1] = 0.0, 0.0            # the zeros' means (and 0 x a coat albedo of 0)
        else:
            b0, b1, b2 = base[0, i], base[1, i], base[2, i]
            sample[0] = (sheen[0, i] + sheen[1, i] + sheen[2, i]) / 3.0
            sample[1] = (coat[0, i] + coat[1, i] + coat[2, i]) / 3.0 * coat_albedo[i]
        mean_base = (b0 + b1 + b2) / 3.0
        sample[2] = s0 * mean_base
        sample[3] = s1 * mean_base
        sample[4] = s2 * mean_base
        weights_out[0, 0, i], weights_out[0, 1, i], weights_out[0, 2, i] = w_metal * b0, w_metal * b1, w_metal * b2
        weights_out[1, 0, i], weights_out[1, 1, i], weights_out[1, 2, i] = w_spec * b0, w_spec * b1, w_spec * b2
        weights_out[2, 0, i], weights_out[2, 1, i], weights_out[2, 2, i] = (w_diffuse * b0, w_diffuse * b1,
                                                                             w_diffuse * b2)
        if n_sample == 6:
            wg = w_glass[i]
            sample[5] = wg * mean_base * glass_weight[i]
            weights_out[3, 0, i], weights_out[3, 1, i], weights_out[3, 2, i] = wg * b0, wg * b1, wg * b2
        total = sample[0]
        for r in range(1, n_sample):
            total = total + sample[r]
        opaque = 1.0 - through[i] if total > 0.0 else 0.0
        prob_out[0, i] = 1.0 - opaque
        for r in range(n_sample):
            prob_out[r + 1, i] = opaque * sample[r] / total if total > 0.0 else 0.0


def _run_lobe_weights(inputs, normalise, w_out, sample_out, layers=None, w_glass=None, glass_weight=None,
                      weights_out=None, prob_out=None):
    """`_lobe_weights` on the per-hit inputs `inputs` (principled.py `_compiled_lobe_inputs`; None
    becomes an empty array) and, where prob_out is given, the layers (layer_weights' namespace)."""
    rows = np.ascontiguousarray
    none, none2, none3 = np.empty(0), np.empty((0, 0)), np.empty((0, 0, 0))
    if layers is None or layers.bare:
        over = (none2, none2, none, none2)
    else:
        over = (rows(layers.sheen), rows(layers.coat), rows(layers.coat_albedo, dtype=np.float64), rows(layers.base))
    _lobe_weights(rows(inputs.mat, dtype=np.int64), rows(inputs.metallic, dtype=np.float64), rows(inputs.wo),
                  rows(inputs.ns), rows(inputs.s_metal).ravel(), rows(inputs.s_spec).ravel(),
                  none2 if inputs.s_hits is None else rows(inputs.s_hits),
                  rows(inputs.metal_colour), rows(inputs.spec_colour),
                  none2 if inputs.dark_metal is None else rows(inputs.dark_metal),
                  none2 if inputs.dark_spec is None else rows(inputs.dark_spec), inputs.has_specular,
                  none if inputs.transmission is None else inputs.transmission, rows(inputs.colour),
                  np.empty(0, dtype=np.bool_) if inputs.glossy_off is None else inputs.glossy_off, inputs.cutoff,
                  inputs.s_metal.shape[1], normalise, w_out, sample_out, *over,
                  rows(layers.alpha, dtype=np.float64) if layers is not None and layers.bare else none,
                  none if layers is None else rows(layers.through, dtype=np.float64),
                  none if w_glass is None else rows(w_glass), none if glass_weight is None else rows(glass_weight),
                  none3 if weights_out is None else weights_out, none2 if prob_out is None else prob_out)


def lobe_weights(inputs, normalise):
    """((w_metal, w_specular, w_diffuse) (N,) each, sample weights or probabilities (3, N)) of
    principled.py lobe_weights; inputs: its per-hit inputs (principled.py `_compiled_lobe_inputs`):
    mat (N,) material ids, metallic (N,) the hits' metallic, wo and ns (3, N) the view and the lobes'
    normal, s_metal and s_spec (M, points) the s(mu) tables, s_hits (2, N) the hits' s of the metal
    and the specular lobe or None (read from the tables), metal_colour and spec_colour (3, N) the
    lobes' F0, dark_metal and dark_spec (3, N) their darkening or None, has_specular (M,),
    transmission (M,) or None (no transmission closure), colour (3, N), glossy_off (N,) or None,
    cutoff; normalise: probabilities."""
    count = len(inputs.mat)
    w, sample = np.empty((3, count)), np.empty((3, count))
    _run_lobe_weights(inputs, normalise, w, sample)
    return (w[0], w[1], w[2]), sample


def layered_lobes(inputs, layers, w_glass=None, glass_weight=None):
    """(closure weights [sheen, coat, metal, specular, diffuse (, glass)] (3, N) each, probabilities
    (6 or 7, N)) of principled.py _layered_lobes in one pass: inputs, those of `lobe_weights`;
    layers, principled.py layer_weights' namespace (where layers.bare, its alpha stands for the base
    weight and its sheen and coat are not read); w_glass, glass_weight (N,): the transmission
    closure's weight and albedo estimate where any material transmits."""
    count = len(inputs.mat)
    glass = w_glass is not None
    out = np.empty((4 if glass else 3, 3, count))
    prob = np.empty((7 if glass else 6, count))
    none2 = np.empty((0, 0))
    _run_lobe_weights(inputs, False, none2, none2, layers, w_glass, glass_weight, out, prob)
    return [layers.sheen, layers.coat, *out], prob


_NO_SCALE = np.empty((0, 0))


def _comp(scale):
    """A compensation (3, N) for the kernels: the array, or an empty one for None (none: 1)."""
    return _NO_SCALE if scale is None else scale


def base_eval(hits, index, wi, tint_metal):
    """(f cos (3, K), pdf (K,)) of the lobes at the pairs (hit index[k], wi[:, k]): the sheen and the
    coat where hits.layered and any hit has one (hits.over_base), then the base; hits: the per-hit
    arrays of principled.py `_fused_hits`, index None for the hits themselves; tint_metal (3, M): the
    metal's edge tints clipped to [0, 1] (principled.py metal_tint)."""
    count = wi.shape[1]
    if index is None:
        index = np.arange(count)
    index = np.ascontiguousarray(index, dtype=np.int64)
    wi = np.ascontiguousarray(wi, dtype=np.float64)
    f_cos, pdf = np.zeros((3, count)), np.zeros(count)
    cos, pdf_g, g = np.empty(count), np.empty(count), np.empty(count)
    if hits.layered and hits.over_base:
        c = hits.coat
        _geometry(index, hits.wo, wi, c.x, c.y, c.n, c.ax, c.ay, c.on, c.on, cos, pdf_g, g)
        s = hits.sheen
        _layers(index, wi, s.x, s.y, s.n, s.a, s.b, s.w, s.on, cos, pdf_g, g, c.w, c.on, c.eta, _comp(c.comp),
                hits.prob, f_cos, pdf)
    _geometry(index, hits.wo, wi, hits.x, hits.y, hits.n, hits.ax, hits.ay, hits.on_metal, hits.on_spec,
              cos, pdf_g, g)
    s5 = np.clip(1.0 - cos, 0.0, 1.0) ** 5 if hits.any_metal else cos     # fresnel_f82's power, NumPy's
    _combine(index, wi, cos, pdf_g, g, s5, hits.nd, hits.w_metal, hits.w_spec, hits.w_diffuse, hits.on_metal,
             hits.on_spec, hits.on_diffuse, hits.prob, hits.base_row, np.asarray(hits.mat, dtype=np.int64),
             hits.f0_metal, tint_metal, _comp(hits.comp_metal), hits.spec_colour, hits.eta, hits.f0_spec,
             _comp(hits.comp_spec), hits.colour, f_cos, pdf)
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
    tint = ones * 0.9
    hits = SimpleNamespace(wo=wo, x=frame[0].copy(), y=frame[1].copy(), n=frame[2].copy(), nd=frame[2].copy(),
                           ax=np.array([0.25, 0.5]), ay=np.array([0.25, 0.5]), w_metal=ones * [1.0, 0.0],
                           w_spec=ones * [0.0, 1.0], w_diffuse=ones * [0.0, 0.5], on_metal=np.array([True, False]),
                           on_spec=np.array([False, True]), on_diffuse=np.array([False, True]),
                           prob=np.ascontiguousarray(np.array([[1.0, 0.0], [0.0, 0.5], [0.0, 0.5]])), base_row=0,
                           mat=np.array([0, 1], dtype=np.int64), f0_metal=ones * 0.5, comp_metal=ones,
                           spec_colour=ones * 0.04, eta=np.array([1.5, 1.5]), f0_spec=np.array([0.04, 0.04]),
                           comp_spec=None, colour=ones * 0.8, any_metal=True, layered=False, over_base=False)
    base_eval(hits, None, wo[::-1].copy(), tint)
    base_eval(hits, np.array([1, 0]), wo.copy(), tint)
    base_pick(hits, np.array([0.3, 0.6]), np.array([0.3, 0.6]), np.array([0.2, 0.9]))
    hits.layered, hits.over_base, hits.base_row = True, True, 3
    hits.prob = np.ascontiguousarray(np.vstack([np.zeros((3, 2)), hits.prob]))
    hits.coat = SimpleNamespace(x=hits.x, y=hits.y, n=hits.n, ax=hits.ax, ay=hits.ay, w=ones * 0.5, on=on,
                                eta=np.array([1.5, 1.5]), comp=ones)
    hits.sheen = SimpleNamespace(x=hits.x, y=hits.y, n=hits.n, a=np.array([0.5, 0.5]), b=np.array([0.1, 0.1]),
                                 w=ones * 0.5, on=on)
    base_eval(hits, None, wo[::-1].copy(), tint)
    base_eval(hits, np.array([1, 0]), wo.copy(), tint)
    wi, _, choice, failed, _ = layered_pick(hits, np.array([0.3, 0.9]), np.array([0.3, 0.6]), np.array([0.2, 0.9]), 50)
    f_cos, pdf = base_eval(hits, None, wi, tint)
    sample_values(f_cos, pdf, choice, hits.prob[0], np.array([0.0, 0.5]), failed)
    sample_values(f_cos, pdf)
    diffuse_directions(np.array([1]), np.array([0.3, 0.6]), np.array([0.2, 0.9]), hits.n, wi, failed)
    layers = SimpleNamespace(sheen=ones * 0.1, coat=ones * 0.2, coat_albedo=np.array([0.1, 0.2]), base=ones * 0.5,
                             through=np.array([0.0, 0.5]), alpha=np.array([1.0, 0.5]), bare=False)
    w = np.array([0.5, 0.25])
    for dark, off in ((None, None), (ones, np.array([True, False]))):
        inputs = SimpleNamespace(mat=np.array([0, 1]), metallic=np.array([0.5, 1.0]), wo=wo, ns=frame[2].copy(),
                                 s_metal=ones * 0.5, s_spec=ones * 0.25,
                                 s_hits=None if dark is None else ones[:2] * 0.5, metal_colour=ones * 0.9,
                                 spec_colour=ones * 0.04, dark_metal=dark, dark_spec=dark,
                                 has_specular=np.array([True, False]),
                                 transmission=None if dark is None else np.array([0.0, 0.5]), colour=ones,
                                 glossy_off=off, cutoff=1e-5)
        for normalise in (False, True):
            lobe_weights(inputs, normalise)
        for bare in (False, True):
            layers.bare = bare
            layered_lobes(inputs, layers)
            layered_lobes(inputs, layers, w, np.array([1.0, 0.9]))
