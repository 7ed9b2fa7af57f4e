"""The GGX lobe's geometry (engine/materials/glossy.py MicrofacetReflection: its eval and sample at
the GGX hits, without the Fresnel and the energy compensation) compiled with numba: one loop over
the hits and no temporaries.  Every hit repeats the NumPy path's float64 operations in the same
order (to_local, the half vector, engine/materials/microfacet.py ggx_d, ggx_lambda and
ggx_sample_vndf, the nan_to_num of the results), with only +, -, *, /, sqrt, cos and sin, which
NumPy and numba compute alike (IEEE 754 and the C library's cos and sin): the same numbers bit for
bit (tests/materials/test_microfacet_jit.py).  Imported only through engine/core/backend.py's
choice (it imports numba)."""
from __future__ import annotations

import math

import numpy as np

from ..core.backend import numba_module
from .microfacet import SQRT_PI

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

BIG = np.finfo(np.float64).max          # what np.nan_to_num makes of +inf
TWO_PI = 2.0 * np.pi
PI = np.pi
TWO_OVER_SQRT_PI = 2.0 / SQRT_PI        # microfacet.py _erfinv's Newton step: (2 / sqrt(pi)) exp(-x^2)
ERFINV_LOW, ERFINV_HIGH = -1.0 + 1e-15, 1.0 - 1e-15


@jit
def _finite(v):
    """np.nan_to_num of a scalar: NaN -> 0, +-inf -> +-BIG."""
    if v != v:
        return 0.0
    if v == np.inf:
        return BIG
    if v == -np.inf:
        return -BIG
    return v


@jit
def _slope_term(w0, w1, w2, ax, ay):
    """microfacet.py slope_term of one direction: alpha^2 tan^2, inf where w2 = 0."""
    if w2 != 0.0:
        a, b = ax * w0, ay * w1
        return (a * a + b * b) / (w2 * w2)
    return np.inf


@jit
def _lambda(w0, w1, w2, ax, ay):
    """ggx_lambda of one direction."""
    return 0.5 * (np.sqrt(1.0 + _slope_term(w0, w1, w2, ax, ay)) - 1.0)


@jit
def _d(h0, h1, h2, ax, ay):
    """ggx_d of one normal: 0 below the surface."""
    a, b = h0 / ax, h1 / ay
    t = a * a + b * b + h2 * h2
    if h2 > 0.0:
        return 1.0 / (PI * ax * ay * t * t)
    return 0.0


@jit
def _max0(v):
    """np.maximum(0.0, v) (NaN stays NaN, -0.0 becomes 0.0)."""
    if v != v:
        return v
    return 0.0 if 0.0 >= v else v


@jit
def _clip01(v):
    """np.clip(v, 0, 1) (NaN stays NaN)."""
    if v < 0.0:
        return 0.0
    if v > 1.0:
        return 1.0
    return v


@jit
def eval_hit(wo, wi, x, y, n, j, k, a_x, a_y):
    """(cos, pdf, g) of GGX reflection for the hit j (wo, frame x, y, n: its column j) and the
    direction wi[:, k] (the body of `ggx_eval`; engine/materials/principled_jit.py calls it too)."""
    o0 = wo[0, j] * x[0, j] + wo[1, j] * x[1, j] + wo[2, j] * x[2, j]
    o1 = wo[0, j] * y[0, j] + wo[1, j] * y[1, j] + wo[2, j] * y[2, j]
    o2 = wo[0, j] * n[0, j] + wo[1, j] * n[1, j] + wo[2, j] * n[2, j]
    i0 = wi[0, k] * x[0, j] + wi[1, k] * x[1, j] + wi[2, k] * x[2, j]
    i1 = wi[0, k] * y[0, j] + wi[1, k] * y[1, j] + wi[2, k] * y[2, j]
    i2 = wi[0, k] * n[0, j] + wi[1, k] * n[1, j] + wi[2, k] * n[2, j]
    ok = (o2 > 0.0) and (i2 > 0.0)
    f0, f1, f2 = o0 + i0, o1 + i1, o2 + i2
    length = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    if not length > 0.0:
        length = 1.0
    h0, h1, h2 = f0 / length, f1 / length, f2 / length
    d = _d(h0, h1, h2, a_x, a_y)
    lo = _lambda(o0, o1, o2, a_x, a_y)
    li = _lambda(i0, i1, i2, a_x, a_y)
    common = d / (4.0 * o2) if ok else 0.0
    return _clip01(o0 * h0 + o1 * h1 + o2 * h2), _finite(common / (1.0 + lo)), _finite(common / (1.0 + lo + li))


@jit
def _eval(wo, wi, x, y, n, ax, ay, cos_out, pdf_out, g_out):
    for i in range(wo.shape[1]):
        cos_out[i], pdf_out[i], g_out[i] = eval_hit(wo, wi, x, y, n, i, i, ax[i], ay[i])


@jit
def _normalized(a0, a1, a2):
    length = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    return a0 / length, a1 / length, a2 / length


@jit
def vndf(o0, o1, o2, a_x, a_y, u1, u2):
    """ggx_sample_vndf of one direction in the local frame: stretch, sample the projected
    hemisphere, unstretch (engine/materials/dielectric_jit.py samples its glass with it too)."""
    v0, v1, v2 = _normalized(a_x * o0, a_y * o1, o2)
    lensq = v0 * v0 + v1 * v1
    if lensq > 1e-14:
        inv = 1.0 / np.sqrt(lensq)
        t0, t1, t2 = -v1 * inv, v0 * inv, 0.0
    else:
        t0, t1, t2 = 1.0, 0.0, 0.0
    s0, s1, s2 = v1 * t2 - v2 * t1, v2 * t0 - v0 * t2, v0 * t1 - v1 * t0
    r = np.sqrt(u1)
    phi = TWO_PI * u2
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + v2)
    p2 = (1.0 - s) * np.sqrt(_max0(1.0 - p1 * p1)) + s * p2
    pz = np.sqrt(_max0(1.0 - p1 * p1 - p2 * p2))
    m0 = p1 * t0 + p2 * s0 + pz * v0
    m1 = p1 * t1 + p2 * s1 + pz * v1
    m2 = p1 * t2 + p2 * s2 + pz * v2
    return _normalized(a_x * m0, a_y * m1, _max0(m2))


@jit
def sample_hit(wo, x, y, n, i, a_x, a_y, u1, u2):
    """(wi (world, 3 scalars), cos, pdf, G2 / G1(wo)) of a GGX visible-normal sample at hit i with
    the uniforms u1, u2 (the body of `ggx_sample`; engine/materials/principled_jit.py calls it too)."""
    o0 = wo[0, i] * x[0, i] + wo[1, i] * x[1, i] + wo[2, i] * x[2, i]
    o1 = wo[0, i] * y[0, i] + wo[1, i] * y[1, i] + wo[2, i] * y[2, i]
    o2 = wo[0, i] * n[0, i] + wo[1, i] * n[1, i] + wo[2, i] * n[2, i]
    h0, h1, h2 = vndf(o0, o1, o2, a_x, a_y, u1, u2)
    # the reflected direction and its weight
    cos_h = o0 * h0 + o1 * h1 + o2 * h2
    w0, w1, w2 = 2.0 * cos_h * h0 - o0, 2.0 * cos_h * h1 - o1, 2.0 * cos_h * h2 - o2
    ok = (o2 > 0.0) and (w2 > 0.0)
    d = _d(h0, h1, h2, a_x, a_y)
    lo = _lambda(o0, o1, o2, a_x, a_y)
    li = _lambda(w0, w1, w2, a_x, a_y)
    if ok:
        pdf = _finite(d / (4.0 * o2 * (1.0 + lo)))
        ratio = (1.0 + lo) / (1.0 + lo + li)
    else:
        pdf = 0.0
        ratio = 0.0
    e0 = w0 * x[0, i] + w1 * y[0, i] + w2 * n[0, i]
    e1 = w0 * x[1, i] + w1 * y[1, i] + w2 * n[1, i]
    e2 = w0 * x[2, i] + w1 * y[2, i] + w2 * n[2, i]
    d0, d1, d2 = _normalized(e0, e1, e2)
    return d0, d1, d2, _clip01(cos_h), pdf, ratio


@jit
def _sample(wo, x, y, n, ax, ay, u1, u2, wi_out, cos_out, pdf_out, ratio_out):
    for i in range(wo.shape[1]):
        wi_out[0, i], wi_out[1, i], wi_out[2, i], cos_out[i], pdf_out[i], ratio_out[i] = sample_hit(
            wo, x, y, n, i, ax[i], ay[i], u1[i], u2[i])


# -- Beckmann (microfacet.py beckmann_d, beckmann_lambda, beckmann_sample_vndf, erf, _erfinv) ----
# Their exp and log are the C library's; NumPy's float64 exp and log on AVX512F machines are its own
# SIMD code, which rounds about one result in four to the other neighbour: within 1 ulp per call.


@jit
def erf(x):
    """microfacet.py erf of one number (Numerical Recipes' Chebyshev fit, the same operations)."""
    z = abs(x)
    t = 1.0 / (1.0 + 0.5 * z)
    poly = (-z * z - 1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 + t * (
        -0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 + t * (
            -0.82215223 + t * 0.17087277)))))))))
    return math.copysign(1.0 - t * np.exp(poly), x)


@jit
def erfinv(y):
    """microfacet.py _erfinv of one number: Giles' start (the branch the NumPy path keeps), two
    Newton steps on `erf`."""
    if y < ERFINV_LOW:                              # np.clip (NaN stays NaN)
        y = ERFINV_LOW
    elif y > ERFINV_HIGH:
        y = ERFINV_HIGH
    w = -np.log((1.0 - y) * (1.0 + y))
    if w < 5.0:
        ws = w - 2.5
        p = 2.81022636e-08
        p = 3.43273939e-07 + p * ws
        p = -3.5233877e-06 + p * ws
        p = -4.39150654e-06 + p * ws
        p = 0.00021858087 + p * ws
        p = -0.00125372503 + p * ws
        p = -0.00417768164 + p * ws
        p = 0.246640727 + p * ws
        p = 1.50140941 + p * ws
    else:
        wl = np.sqrt(w) - 3.0
        p = -0.000200214257
        p = 0.000100950558 + p * wl
        p = 0.00134934322 + p * wl
        p = -0.00367342844 + p * wl
        p = 0.00573950773 + p * wl
        p = -0.0076224613 + p * wl
        p = 0.00943887047 + p * wl
        p = 1.00167406 + p * wl
        p = 2.83297682 + p * wl
    x = p * y
    for _ in range(2):
        x = x - (erf(x) - y) / (TWO_OVER_SQRT_PI * np.exp(-x * x))
    return x


@jit
def beckmann_d(h0, h1, h2, ax, ay):
    """beckmann_d of one normal (its nan_to_num included): 0 below the surface."""
    if not h2 > 0.0:
        return 0.0
    z2 = h2 * h2
    a, b = h0 / ax, h1 / ay
    return _finite(np.exp(-(a * a + b * b) / z2) / (PI * ax * ay * z2 * z2))


@jit
def beckmann_lambda(w0, w1, w2, ax, ay):
    """beckmann_lambda of one direction: 0 along the normal, inf where the formula is not finite."""
    s = _slope_term(w0, w1, w2, ax, ay)
    if not s > 0.0:
        return 0.0
    a = 1.0 / np.sqrt(s)
    lam = 0.5 * (erf(a) - 1.0) + np.exp(-a * a) / (2.0 * a * SQRT_PI)
    if not math.isfinite(lam):
        return np.inf
    return lam if lam >= 0.0 else 0.0


@jit
def _slope_cdf(x, k):
    """The visible-slope CDF (unnormalised) of beckmann_sample_vndf."""
    return 1.0 + erf(x) + k * np.exp(-x * x)


SLOPE_STEPS = 48                # beckmann_sample_vndf's bisection steps
SLOPE_LOW = -8.0                # and the low end of its bracket
CERTAIN = 1e-13                 # visible_slope's margin in CDF units: 100 x the CDF's rounding


@jit
def _bisect(hi, k, target):
    """beckmann_sample_vndf's bisection: SLOPE_STEPS halvings of [SLOPE_LOW, hi], the CDF at every mid."""
    lo = SLOPE_LOW
    for _ in range(SLOPE_STEPS):
        mid = 0.5 * (lo + hi)
        if _slope_cdf(mid, k) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@jit
def _slope_root(hi, k, target):
    """(x, CDF'(x)) with CDF(x) = target on [SLOPE_LOW, hi] by Newton's method kept in the bracket
    (a bisection step where Newton's leaves it), to 1 % of visible_slope's margin; CDF' 0 where it
    does not converge in 40 steps."""
    a, b = SLOPE_LOW, hi
    x = 0.0 if b > 0.0 else 0.5 * (a + b)
    for _ in range(40):
        e = np.exp(-x * x)
        slope = e * (TWO_OVER_SQRT_PI - 2.0 * k * x)
        c = _slope_cdf(x, k)
        if c < target:
            a = x
        else:
            b = x
        step = (c - target) / slope
        x_new = x - step
        if abs(step) <= 0.01 * CERTAIN * max(1.0, target) / slope:
            return x_new, slope
        x = x_new if a < x_new < b else 0.5 * (a + b)
    return x, 0.0


@jit
def visible_slope(hi, k, target):
    """_bisect's result (the same steps, the same CDF where it decides), computing the CDF only at
    the mids within CERTAIN of the root: elsewhere the side of the root decides, as the CDF is
    increasing on the bracket and its rounding (about 1e-16 of max(1, target)) is far smaller than
    its change over that distance.  Where the root is in the flat tails (x < -3.5, CDF' < 1e-4), the
    CDF is not increasing (k < 0: the lower hemisphere) or not finite, every mid's CDF decides.
    About 10 CDFs instead of 48 (tests/materials/test_microfacet_jit.py: the same bits as _bisect)."""
    root, slope = _slope_root(hi, k, target)
    if not (k >= 0.0 and root > -3.5 and slope > 1e-4 and np.isfinite(target) and np.isfinite(hi)):
        return _bisect(hi, k, target)
    certain = CERTAIN * max(1.0, target) / slope
    lo = SLOPE_LOW
    for _ in range(SLOPE_STEPS):
        mid = 0.5 * (lo + hi)
        if mid < root - certain:
            below = True
        elif mid > root + certain:
            below = False
        else:
            below = _slope_cdf(mid, k) < target
        if below:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@jit
def beckmann_vndf(o0, o1, o2, a_x, a_y, u1, u2):
    """beckmann_sample_vndf of one direction: stretch, the slope x of the visible-slope CDF
    (`visible_slope`: its bisection's result), the slope y = erfinv(2 u2 - 1), rotate, unstretch."""
    v0, v1, v2 = _normalized(a_x * o0, a_y * o1, o2)
    sin_t = np.sqrt(_max0(1.0 - v2 * v2))
    if sin_t > 1e-7:
        cos_phi, sin_phi = v0 / sin_t, v1 / sin_t
        k, cot = sin_t / (v2 * SQRT_PI), v2 / sin_t
    else:
        cos_phi, sin_phi, k, cot = 1.0, 0.0, 0.0, np.inf
    hi = cot if (cot <= 8.0 or cot != cot) else 8.0        # np.minimum(cot, 8.0)
    sx = visible_slope(hi, k, u1 * _slope_cdf(hi, k))
    sy = erfinv(2.0 * u2 - 1.0)
    rx = cos_phi * sx - sin_phi * sy
    ry = sin_phi * sx + cos_phi * sy
    return _normalized(-rx * a_x, -ry * a_y, 1.0)


@jit
def _tinted_eval(index, wo, wi, x, y, n, ax, ay, colour, comp, f_out, pdf_out):
    """f cos = colour x g x compensation and pdf of the pairs (hit index[k], wi[:, k]): the lobe of
    Fresnel "none" (MicrofacetReflection.eval's numbers)."""
    for k in range(index.shape[0]):
        j = index[k]
        _, pdf, g = eval_hit(wo, wi, x, y, n, j, k, ax[j], ay[j])
        for ch in range(3):
            f_out[ch, k] = colour[ch, j] * g * comp[ch, j]
        pdf_out[k] = pdf


@jit
def _basis(n0, n1, n2):
    """engine/sampling/warps.py orthonormal_basis of one normal (Duff et al.): (tangent, bitangent)."""
    sign = math.copysign(1.0, n2)
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    return (1.0 + sign * n0 * n0 * a, sign * b, -sign * n0), (b, sign + n1 * n1 * a, -n1)


@jit
def _frame(n, t, x_out, y_out):
    """engine/materials/microfacet.py shading_frame(n, t) per hit: t made orthogonal to n (Gram-Schmidt),
    orthonormal_basis's tangent where that is shorter than 1e-9 (or NaN); y = n x x."""
    for i in range(n.shape[1]):
        n0, n1, n2 = n[0, i], n[1, i], n[2, i]
        if t.shape[1] == 0:                         # no tangent: orthonormal_basis
            (x0, x1, x2), (y0, y1, y2) = _basis(n0, n1, n2)
            x_out[0, i], x_out[1, i], x_out[2, i] = x0, x1, x2
            y_out[0, i], y_out[1, i], y_out[2, i] = y0, y1, y2
            continue
        t0, t1, t2 = t[0, i], t[1, i], t[2, i]
        d = t0 * n0 + t1 * n1 + t2 * n2
        x0, x1, x2 = t0 - d * n0, t1 - d * n1, t2 - d * n2
        length = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if length > 1e-9:
            x0, x1, x2 = x0 / length, x1 / length, x2 / length
        else:
            (x0, x1, x2), _ = _basis(n0, n1, n2)
        x_out[0, i], x_out[1, i], x_out[2, i] = x0, x1, x2
        y_out[0, i] = n1 * x2 - n2 * x1
        y_out[1, i] = n2 * x0 - n0 * x2
        y_out[2, i] = n0 * x1 - n1 * x0


def frame(n, tangent=None):
    """(x, y) (3, N) each of engine/materials/microfacet.py shading_frame(n, tangent), tangent (3, N)
    or None: the same numbers."""
    count = n.shape[1]
    x, y = np.empty((3, count)), np.empty((3, count))
    t = np.empty((3, 0)) if tangent is None else _rows(np.broadcast_to(np.reshape(tangent, (3, -1)), (3, count)))
    _frame(_rows(n), t, x, y)
    return x, y


def _rows(a):
    return np.ascontiguousarray(a, dtype=np.float64)


def _per_hit(a, count):
    return np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=np.float64), (count,)))


def ggx_eval(wo, wi, x, y, n, ax, ay):
    """(cos = clip(wo.h, 0, 1), pdf, g) (N,) each of GGX reflection in the frame (x, y, n): pdf =
    D / (4 cos_o (1 + Lambda(wo))) and g = D / (4 cos_o (1 + Lambda(wo) + Lambda(wi))) where both
    directions are above (0 elsewhere), as MicrofacetReflection.eval computes them."""
    count = wo.shape[1]
    cos, pdf, g = np.empty(count), np.empty(count), np.empty(count)
    _eval(_rows(wo), _rows(wi), _rows(x), _rows(y), _rows(n), _per_hit(ax, count), _per_hit(ay, count), cos, pdf, g)
    return cos, pdf, g


def ggx_sample(wo, x, y, n, ax, ay, u1, u2):
    """(wi (3, N) world, cos = clip(wo.h, 0, 1), pdf, G2 / G1(wo)) of a GGX visible-normal sample,
    as MicrofacetReflection.sample computes them (pdf after its nan_to_num)."""
    count = wo.shape[1]
    wi = np.empty((3, count))
    cos, pdf, ratio = np.empty(count), np.empty(count), np.empty(count)
    _sample(_rows(wo), _rows(x), _rows(y), _rows(n), _per_hit(ax, count), _per_hit(ay, count),
            _per_hit(u1, count), _per_hit(u2, count), wi, cos, pdf, ratio)
    return wi, cos, pdf, ratio


def tinted_eval(hits, index, wi):
    """(f cos (3, K), pdf (K,)) of a GGX lobe whose Fresnel is its colour at the pairs (hit index[k],
    wi[:, k]); hits: the per-hit arrays of engine/materials/glossy.py `_tinted_hits`, index None for
    the hits themselves."""
    count = wi.shape[1]
    index = np.arange(count) if index is None else np.ascontiguousarray(index, dtype=np.int64)
    f_cos, pdf = np.empty((3, count)), np.empty(count)
    _tinted_eval(index, hits.wo, _rows(wi), hits.x, hits.y, hits.n, hits.ax, hits.ay, hits.colour, hits.comp,
                 f_cos, pdf)
    return f_cos, pdf


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    w = np.array([[0.1, 0.0], [0.2, 0.0], [0.97, 1.0]])
    eye = np.eye(3)[:, :, None].repeat(2, axis=2)
    a = np.array([0.25, 0.5])
    ggx_eval(w, w[::-1].copy(), eye[0], eye[1], eye[2], a, a)
    ggx_sample(w, eye[0], eye[1], eye[2], a, a, np.array([0.3, 0.6]), np.array([0.2, 0.9]))
    from types import SimpleNamespace
    hits = SimpleNamespace(wo=w, x=eye[0].copy(), y=eye[1].copy(), n=eye[2].copy(), ax=a, ay=a,
                           colour=np.ones((3, 2)), comp=np.ones((3, 2)))
    tinted_eval(hits, None, w[::-1].copy())
    tinted_eval(hits, np.array([1, 0]), w.copy())
    frame(w, np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]))
    frame(w)
