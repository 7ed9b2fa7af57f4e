"""The rough dielectric lobe (engine/materials/dielectric_lobe.py MicrofacetDielectric: its sample
and eval with the dielectric Fresnel, in the local frame) compiled with numba: one loop over the hits
and no temporaries.  Every hit repeats the NumPy path's float64 operations in the same order
(engine/materials/microfacet.py ggx_sample_vndf, ggx_d, ggx_lambda, or at Beckmann hits
beckmann_sample_vndf, beckmann_d, beckmann_lambda; engine/materials/glossy.py fresnel_dielectric;
the lobe's split, _jacobian, _g2 and the nan_to_num of its results), with the scalar helpers of
engine/materials/microfacet_jit.py.  GGX hits use only +, -, *, /, sqrt, cos and sin: the same
numbers bit for bit.  Beckmann hits also call exp and log, which are the C library's here and
NumPy's own SIMD code on AVX512F machines, 1 ulp apart in about one call in four: their results
agree to about 1e-15 relative, rarely more where the sampled slope's bisection turns the other way
at its last steps (tests/materials/test_dielectric_jit.py; docs/performance.md, branch beckmann3).
The Principled BSDF's glass closure's coloured Fresnel (dielectric_lobe.py RealFresnel: R and T per
channel, the reflection picked by their channel means) has kernels of its own (`sample_coloured`,
`eval_coloured`, and its albedo estimate `albedo_coloured`); other Fresnel functions and the albedo
tables' sampling stay NumPy's.  `frame` (microfacet_jit.py's shading_frame twin) is the glass
BSDFs' frame and `energy_scale` their multiscatter GGX compensation (engine/materials/dielectric.py
energy_scale: its albedo tables read per hit, bit for bit).  Imported only through the lobe's
backend choice (it imports numba)."""
from __future__ import annotations

import numpy as np

from .microfacet_jit import (_clip01, _d, _finite, _lambda, _max0, _normalized, beckmann_d, beckmann_lambda,
                             beckmann_vndf, frame, jit, vndf)  # noqa: F401 (frame: the glass BSDFs')
from . import glass_albedo
from .glass_albedo import SIZE
from .principled_jit import _fresnel_dielectric


@jit
def _split(cos_h, eta, reflection, transmission):
    """MicrofacetDielectric.split: (R, T)."""
    f = _fresnel_dielectric(cos_h, eta)
    if not transmission:
        return f, 0.0
    if not reflection:
        return 0.0, (0.0 if f >= 1.0 else 1.0)
    return f, 1.0 - f


@jit
def _jacobian(cos_ho, cos_hi, eta, refracted):
    if refracted:
        s = cos_hi + cos_ho / eta
        return abs(cos_ho * cos_hi) / (s * s)
    return 0.25


@jit
def _g2(lo, li, separable):
    if separable:
        return 1.0 / ((1.0 + lo) * (1.0 + li))
    return 1.0 / (1.0 + lo + li)


@jit
def _normal(beckmann, o0, o1, o2, a, u1, u2):
    """A visible microfacet normal of the hit's distribution (isotropic alpha a)."""
    if beckmann:
        return beckmann_vndf(o0, o1, o2, a, a, u1, u2)
    return vndf(o0, o1, o2, a, a, u1, u2)


@jit
def _terms(beckmann, h0, h1, h2, o0, o1, o2, w0, w1, w2, a):
    """MicrofacetDielectric._terms of one hit: (D(h), Lambda(wo), Lambda(wi with |z|))."""
    if beckmann:
        return (beckmann_d(h0, h1, h2, a, a), beckmann_lambda(o0, o1, o2, a, a),
                beckmann_lambda(w0, w1, abs(w2), a, a))
    return _d(h0, h1, h2, a, a), _lambda(o0, o1, o2, a, a), _lambda(w0, w1, abs(w2), a, a)


@jit
def _sample(wo, alpha, eta, beckmann, u_lobe, u1, u2, separable, reflection, transmission,
            wi_out, weight_out, pdf_out, refracted_out, ok_out):
    for i in range(wo.shape[1]):
        o0, o1, o2 = wo[0, i], wo[1, i], wo[2, i]
        a, e = alpha[i], eta[i]
        h0, h1, h2 = _normal(beckmann[i], o0, o1, o2, a, u1[i], u2[i])
        cos_ho = _clip01(o0 * h0 + o1 * h1 + o2 * h2)
        r, t = _split(cos_ho, e, reflection, transmission)
        total = r + t
        p_reflect = r / total if total > 0.0 else 0.0
        cos_t = np.sqrt(_max0(1.0 - (1.0 - cos_ho * cos_ho) / (e * e)))
        refracted = u_lobe[i] >= p_reflect
        if refracted:
            k = cos_ho / e - cos_t
            w0, w1, w2 = -o0 / e + k * h0, -o1 / e + k * h1, -o2 / e + k * h2
        else:
            c = 2.0 * cos_ho
            w0, w1, w2 = c * h0 - o0, c * h1 - o1, c * h2 - o2
        w0, w1, w2 = _normalized(w0, w1, w2)
        ok = (o2 > 0.0) and (total > 0.0) and ((w2 < 0.0) if refracted else (w2 > 0.0))
        d, lo, li = _terms(beckmann[i], h0, h1, h2, o0, o1, o2, w0, w1, w2, a)
        cos_hi = w0 * h0 + w1 * h1 + w2 * h2
        lobe = 1.0 - p_reflect if refracted else p_reflect
        if ok:
            common = d / o2 * _jacobian(cos_ho, cos_hi, e, refracted)
            pdf = lobe * common / (1.0 + lo)
            weight = (t if refracted else r) / lobe * (1.0 + lo) * _g2(lo, li, separable[i])
        else:
            pdf, weight = 0.0, 0.0
        wi_out[0, i], wi_out[1, i], wi_out[2, i] = w0, w1, w2
        weight_out[i], pdf_out[i] = _finite(weight), _finite(pdf)
        refracted_out[i] = refracted
        ok_out[i] = ok and pdf > 0.0


@jit
def _half_vector(o0, o1, o2, i0, i1, i2, e, reflection, transmission):
    """The eval kernels' shared start: (ok, refracted, h, cos_ho, cos_hi) of the pair (wo, wi) at
    relative eta e: the half vector of reflection (wo + wi) or refraction (-(wo + e wi)), turned to
    the normal's side, and whether the pair is one the lobes allow."""
    refracted = i2 < 0.0
    if refracted:
        f0, f1, f2 = -(o0 + e * i0), -(o1 + e * i1), -(o2 + e * i2)
    else:
        f0, f1, f2 = o0 + i0, o1 + i1, o2 + i2
    length = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    scale = length if length > 0.0 else 1.0
    h0, h1, h2 = f0 / scale, f1 / scale, f2 / scale
    if h2 < 0.0:
        h0, h1, h2 = h0 * -1.0, h1 * -1.0, h2 * -1.0
    cos_ho = o0 * h0 + o1 * h1 + o2 * h2
    cos_hi = i0 * h0 + i1 * h1 + i2 * h2
    ok = ((o2 > 0.0) and (i2 != 0.0) and (length > 0.0) and (cos_ho > 0.0)
          and ((cos_hi < 0.0) if refracted else (cos_hi > 0.0)))
    if transmission and not reflection:
        ok = ok and refracted
    if not transmission:
        ok = ok and not refracted
    return ok, refracted, h0, h1, h2, cos_ho, cos_hi


@jit
def _eval(wo, wi, alpha, eta, beckmann, separable, reflection, transmission, f_out, pdf_out):
    for i in range(wo.shape[1]):
        o0, o1, o2 = wo[0, i], wo[1, i], wo[2, i]
        i0, i1, i2 = wi[0, i], wi[1, i], wi[2, i]
        a, e = alpha[i], eta[i]
        ok, refracted, h0, h1, h2, cos_ho, cos_hi = _half_vector(o0, o1, o2, i0, i1, i2, e, reflection, transmission)
        if not ok:
            f_out[i], pdf_out[i] = 0.0, 0.0
            continue
        r, t = _split(_clip01(cos_ho), e, reflection, transmission)
        total = r + t
        d, lo, li = _terms(beckmann[i], h0, h1, h2, o0, o1, o2, i0, i1, i2, a)
        p_reflect = r / total if total > 0.0 else 0.0
        lobe = 1.0 - p_reflect if refracted else p_reflect
        common = d / o2 * _jacobian(cos_ho, cos_hi, e, refracted)
        pdf_out[i] = _finite(lobe * common / (1.0 + lo))
        f_out[i] = _finite((t if refracted else r) * common * _g2(lo, li, separable[i]))


@jit
def _real_fresnel(cos_h, eta, f0, tint, i):
    """dielectric_lobe.py RealFresnel at hit i: (R_r, R_g, R_b, T_r, T_g, T_b), and the channel means
    of R and of R + T (dielectric_lobe._mean: (c0 + c1 + c2) / 3, NumPy's row-wise sum then divide)."""
    q = (eta - 1.0) / (eta + 1.0)
    f0_real = q * q
    s = (_fresnel_dielectric(cos_h, eta) - f0_real) / (1.0 - f0_real)
    if s != s:
        s = 1.0
    s = _clip01(s)
    r0 = f0[0, i] + (1.0 - f0[0, i]) * s
    r1 = f0[1, i] + (1.0 - f0[1, i]) * s
    r2 = f0[2, i] + (1.0 - f0[2, i]) * s
    t0, t1, t2 = (1.0 - r0) * tint[0, i], (1.0 - r1) * tint[1, i], (1.0 - r2) * tint[2, i]
    mean_r = (r0 + r1 + r2) / 3.0
    total = ((r0 + t0) + (r1 + t1) + (r2 + t2)) / 3.0
    return r0, r1, r2, t0, t1, t2, mean_r, total


@jit
def _albedo_coloured(cos, eta, f0, tint, out):
    """principled_glass.py PrincipledGlass._albedo per hit: the channel mean of R + T at cos clipped to
    [0, 1] (`_real_fresnel`'s total)."""
    for i in range(cos.shape[0]):
        out[i] = _real_fresnel(_clip01(cos[i]), eta[i], f0, tint, i)[7]


@jit
def _sample_coloured(wo, alpha, eta, beckmann, u_lobe, u1, u2, separable, feta, f0, tint,
                     wi_out, weight_out, pdf_out, refracted_out, ok_out):
    """_sample with RealFresnel's coloured (R, T): the weight (3, N); reflection and refraction both."""
    for i in range(wo.shape[1]):
        o0, o1, o2 = wo[0, i], wo[1, i], wo[2, i]
        a, e = alpha[i], eta[i]
        h0, h1, h2 = _normal(beckmann[i], o0, o1, o2, a, u1[i], u2[i])
        cos_ho = _clip01(o0 * h0 + o1 * h1 + o2 * h2)
        r0, r1, r2, t0, t1, t2, mean_r, total = _real_fresnel(cos_ho, feta[i], f0, tint, i)
        p_reflect = mean_r / total if total > 0.0 else 0.0
        cos_t = np.sqrt(_max0(1.0 - (1.0 - cos_ho * cos_ho) / (e * e)))
        refracted = u_lobe[i] >= p_reflect
        if refracted:
            k = cos_ho / e - cos_t
            w0, w1, w2 = -o0 / e + k * h0, -o1 / e + k * h1, -o2 / e + k * h2
        else:
            c = 2.0 * cos_ho
            w0, w1, w2 = c * h0 - o0, c * h1 - o1, c * h2 - o2
        w0, w1, w2 = _normalized(w0, w1, w2)
        ok = (o2 > 0.0) and (total > 0.0) and ((w2 < 0.0) if refracted else (w2 > 0.0))
        d, lo, li = _terms(beckmann[i], h0, h1, h2, o0, o1, o2, w0, w1, w2, a)
        cos_hi = w0 * h0 + w1 * h1 + w2 * h2
        lobe = 1.0 - p_reflect if refracted else p_reflect
        if ok:
            common = d / o2 * _jacobian(cos_ho, cos_hi, e, refracted)
            pdf = lobe * common / (1.0 + lo)
            g2 = _g2(lo, li, separable[i])
            if refracted:
                x0, x1, x2 = t0, t1, t2
            else:
                x0, x1, x2 = r0, r1, r2
            weight_out[0, i] = _finite(x0 / lobe * (1.0 + lo) * g2)
            weight_out[1, i] = _finite(x1 / lobe * (1.0 + lo) * g2)
            weight_out[2, i] = _finite(x2 / lobe * (1.0 + lo) * g2)
        else:
            pdf = 0.0
            weight_out[0, i], weight_out[1, i], weight_out[2, i] = 0.0, 0.0, 0.0
        wi_out[0, i], wi_out[1, i], wi_out[2, i] = w0, w1, w2
        pdf_out[i] = _finite(pdf)
        refracted_out[i] = refracted
        ok_out[i] = ok and pdf > 0.0


@jit
def _eval_coloured(wo, wi, alpha, eta, beckmann, separable, reflection, transmission, feta, f0, tint, f_out, pdf_out):
    """_eval with RealFresnel's coloured (R, T): f cos (3, N)."""
    for i in range(wo.shape[1]):
        o0, o1, o2 = wo[0, i], wo[1, i], wo[2, i]
        i0, i1, i2 = wi[0, i], wi[1, i], wi[2, i]
        a, e = alpha[i], eta[i]
        ok, refracted, h0, h1, h2, cos_ho, cos_hi = _half_vector(o0, o1, o2, i0, i1, i2, e, reflection, transmission)
        if not ok:
            f_out[0, i], f_out[1, i], f_out[2, i], pdf_out[i] = 0.0, 0.0, 0.0, 0.0
            continue
        r0, r1, r2, t0, t1, t2, mean_r, total = _real_fresnel(_clip01(cos_ho), feta[i], f0, tint, i)
        d, lo, li = _terms(beckmann[i], h0, h1, h2, o0, o1, o2, i0, i1, i2, a)
        p_reflect = mean_r / total if total > 0.0 else 0.0
        lobe = 1.0 - p_reflect if refracted else p_reflect
        common = d / o2 * _jacobian(cos_ho, cos_hi, e, refracted)
        pdf_out[i] = _finite(lobe * common / (1.0 + lo))
        g2 = _g2(lo, li, separable[i])
        if refracted:
            x0, x1, x2 = t0, t1, t2
        else:
            x0, x1, x2 = r0, r1, r2
        f_out[0, i] = _finite(x0 * common * g2)
        f_out[1, i] = _finite(x1 * common * g2)
        f_out[2, i] = _finite(x2 * common * g2)


# -- the multiscatter GGX glass's compensation (engine/materials/dielectric.py energy_scale) ----------
LAST = SIZE - 1                 # the tables' last index


@jit
def _coords(x):
    """glass_albedo._coords of one number: (i, min(i + 1, LAST), fraction)."""
    x = _clip01(x) * LAST
    i = min(int(x), LAST)
    return i, min(i + 1, LAST), x - i


@jit
def _bilinear(table, z, x, y):
    """glass_albedo._read_2d_stack of one point: bilinear in (x = roughness, y) over table[z, y, x]
    (its row y0, its row y1, then between them)."""
    x0, x1, tx = _coords(x)
    y0, y1, ty = _coords(y)
    row = table[z]
    return (1.0 - ty) * ((1.0 - tx) * row[y0, x0] + tx * row[y0, x1]) + ty * ((1.0 - tx) * row[y1, x0] + tx * row[y1, x1])


@jit
def _energy_scale(roughness, mu, eta, tint, e_table, e_inv, e_avg_table, e_avg_inv, out):
    for i in range(roughness.shape[0]):
        r, m, n = roughness[i], _clip01(mu[i]), eta[i]
        if np.isnan(r + m) or not np.isfinite(n):      # off the tables: NaN, none of them read
            for ch in range(3):
                out[ch, i] = np.nan
            continue
        z = np.sqrt(abs((n - 1.0) / (n + 1.0)))
        z0, z1, tz = _coords(z)
        table, average = (e_table, e_avg_table) if n >= 1.0 else (e_inv, e_avg_inv)
        e = (1.0 - tz) * _bilinear(table, z0, r, m) + tz * _bilinear(table, z1, r, m)
        e_avg = _bilinear(average, 0, r, z)
        missing = (1.0 - e) / e if e > 0.0 else 0.0
        for ch in range(3):
            c = tint[ch, i]
            out[ch, i] = 1.0 + c * e_avg / (1.0 - c * (1.0 - e_avg)) * missing


def energy_scale(roughness, mu, eta, tint):
    """dielectric.py energy_scale (3, N) of roughness, mu = wo.z and eta (N,) each and the tint (3, N):
    the same numbers (only +, -, *, / and sqrt; the tables read at the same points; NaN off them)."""
    t = glass_albedo.tables()
    count = len(roughness)
    out = np.empty((3, count))
    _energy_scale(_writable(roughness, (count,)), _writable(mu, (count,)), _writable(eta, (count,)),
                  _writable(tint, (3, count)), t["E"], t["E_inv"], t["E_avg"][None], t["E_avg_inv"][None], out)
    return out


def _writable(a, shape):
    """a broadcast to `shape`, float64, C-contiguous and writable (a copy where it was not): one array
    type whatever the caller passes (a read-only broadcast tint, a view), the type warm_up compiled."""
    return np.require(np.broadcast_to(np.asarray(a, dtype=np.float64), shape), requirements=("C", "W"))


def _rows(a):
    return np.ascontiguousarray(a, dtype=np.float64)


def _flags(separable, count):
    """A bool per hit, C-contiguous and writable (None: all False)."""
    if separable is None:
        return np.zeros(count, dtype=np.bool_)
    return np.require(np.broadcast_to(np.asarray(separable, dtype=np.bool_), (count,)), requirements=("C", "W"))


def sample(wo, alpha, eta, beckmann, u_lobe, u1, u2, separable, reflection, transmission):
    """(wi, weight, pdf, refracted, ok) of MicrofacetDielectric.sample, fresnel None; beckmann: a bool per
    hit (else GGX)."""
    count = wo.shape[1]
    wi = np.empty((3, count))
    weight, pdf = np.empty(count), np.empty(count)
    refracted, ok = np.empty(count, dtype=np.bool_), np.empty(count, dtype=np.bool_)
    _sample(_rows(wo), _rows(alpha), _rows(eta), _flags(beckmann, count), _rows(u_lobe), _rows(u1), _rows(u2), _flags(separable, count),
            bool(reflection), bool(transmission), wi, weight, pdf, refracted, ok)
    return wi, weight, pdf, refracted, ok


def eval(wo, wi, alpha, eta, beckmann, separable, reflection, transmission):
    """(f cos / tint, pdf) of MicrofacetDielectric.eval, fresnel None."""
    count = wo.shape[1]
    f_cos, pdf = np.empty(count), np.empty(count)
    _eval(_rows(wo), _rows(wi), _rows(alpha), _rows(eta), _flags(beckmann, count), _flags(separable, count), bool(reflection),
          bool(transmission), f_cos, pdf)
    return f_cos, pdf


def _fresnel_rows(fresnel, count):
    """RealFresnel's eta (N,), f0 and tint (3, N), C-contiguous float64."""
    return (_rows(np.broadcast_to(fresnel.eta, (count,))), _rows(np.broadcast_to(fresnel.f0, (3, count))),
            _rows(np.broadcast_to(fresnel.tint, (3, count))))


def sample_coloured(wo, alpha, eta, beckmann, u_lobe, u1, u2, separable, reflection, transmission, fresnel):
    """(wi, weight (3, N), pdf, refracted, ok) of MicrofacetDielectric.sample with
    fresnel a dielectric_lobe.RealFresnel (both lobes: the Principled glass closure)."""
    if not (reflection and transmission):
        raise ValueError("the coloured Fresnel's compiled sample is the glass's: reflection and transmission")
    count = wo.shape[1]
    wi, weight = np.empty((3, count)), np.empty((3, count))
    pdf = np.empty(count)
    refracted, ok = np.empty(count, dtype=np.bool_), np.empty(count, dtype=np.bool_)
    _sample_coloured(_rows(wo), _rows(alpha), _rows(eta), _flags(beckmann, count), _rows(u_lobe), _rows(u1), _rows(u2),
                     _flags(separable, count), *_fresnel_rows(fresnel, count), wi, weight, pdf, refracted, ok)
    return wi, weight, pdf, refracted, ok


def albedo_coloured(cos, fresnel):
    """mean(R + T) (N,) of a RealFresnel at cos (N,) clipped to [0, 1] (the glass closure's albedo
    estimate, principled_glass.py PrincipledGlass._albedo)."""
    count = cos.shape[0]
    out = np.empty(count)
    _albedo_coloured(_rows(cos), *_fresnel_rows(fresnel, count), out)
    return out


def eval_coloured(wo, wi, alpha, eta, beckmann, separable, reflection, transmission, fresnel):
    """(f cos (3, N), pdf) of MicrofacetDielectric.eval with fresnel a RealFresnel."""
    count = wo.shape[1]
    f_cos, pdf = np.empty((3, count)), np.empty(count)
    _eval_coloured(_rows(wo), _rows(wi), _rows(alpha), _rows(eta), _flags(beckmann, count), _flags(separable, count), bool(reflection),
                   bool(transmission), *_fresnel_rows(fresnel, count), f_cos, pdf)
    return f_cos, pdf


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    wo = np.array([[0.1, 0.0], [0.2, 0.0], [0.97, 1.0]])
    wi = np.array([[0.1, 0.3], [-0.2, 0.0], [0.9, -0.95]])
    a, e, u = np.array([0.25, 0.5]), np.array([1.5, 1.0 / 1.5]), np.array([0.3, 0.7])
    beckmann = np.array([False, True])
    for reflection in (True, False):
        sample(wo, a, e, beckmann, u, u, u[::-1], None, reflection, True)
        eval(wo, wi, a, e, beckmann, np.array([True, False]), reflection, True)
    from .dielectric_lobe import RealFresnel
    fresnel = RealFresnel(e, np.full((3, 2), 0.04), np.full((3, 2), 0.9))
    sample_coloured(wo, a, e, beckmann, u, u, u[::-1], None, True, True, fresnel)
    eval_coloured(wo, wi, a, e, beckmann, None, True, True, fresnel)
    albedo_coloured(wo[2], fresnel)
    energy_scale(a, wo[2], e, np.full((3, 2), 0.9))
