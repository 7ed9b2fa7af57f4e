"""Microfacet distributions, vectorised over rows (3, N) of directions in a local shading frame
(z = the shading normal, x = the tangent): GGX (Trowbridge-Reitz) and Beckmann, isotropic and
anisotropic, with Smith's masking Lambda, G1, the height-correlated G2 (Heitz 2014, "Understanding
the Masking-Shadowing Function", eq. 99) and the separable G1 G1 of Blender 3.4, and sampling of the
visible normals: Heitz 2018 ("Sampling the GGX Distribution of Visible Normals", as Cycles 3.5+)
for GGX, Heitz & d'Eon 2014 for Beckmann.  The formulas follow those papers and Cycles'
bsdf_microfacet.h (a public source: blender/cycles src/kernel/closure/).

Roughness maps to alpha as Blender's nodes do: alpha = roughness^2 (clamped to [0, 1], as
Cycles' setup saturates alpha), floored at ALPHA_MIN: Cycles treats alpha_x alpha_y <= 2e-10
as a perfect mirror; here the mirror kind is the perfect mirror and a glossy lobe stays a lobe.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import cross, dot, normalize
from ..sampling.warps import orthonormal_basis

GGX = "ggx"
BECKMANN = "beckmann"
DISTRIBUTIONS = (GGX, BECKMANN)
ALPHA_MIN = 1e-4                    # roughness 0.01; below it the lobe is narrower than float32 shows
SQRT_PI = np.sqrt(np.pi)


def glossy_alphas(roughness: float, anisotropy: float = 0.0) -> tuple[float, float]:
    """(alpha_x, alpha_y) of Blender's Glossy / Anisotropic BSDF node (Cycles' svm closure.h):
    alpha = clamp(roughness)^2, anisotropy clamped to [-0.99, 0.99] stretches along the tangent
    (a > 0: alpha_x = alpha (1 - a), alpha_y = alpha / (1 - a); a < 0: alpha_x = alpha / (1 + a),
    alpha_y = alpha (1 + a))."""
    alpha = min(max(roughness, 0.0), 1.0) ** 2
    a = min(max(anisotropy, -0.99), 0.99)
    if abs(a) <= 1e-4:
        ax = ay = alpha
    elif a > 0.0:
        ax, ay = alpha * (1.0 - a), alpha / (1.0 - a)
    else:
        ax, ay = alpha / (1.0 + a), alpha * (1.0 + a)
    return clamp_alpha(ax), clamp_alpha(ay)


def glossy_alpha_rows(roughness: np.ndarray, anisotropy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """glossy_alphas over arrays (N,): per-hit roughness from a texture (engine/materials/textures.py)."""
    alpha = np.clip(roughness, 0.0, 1.0) ** 2
    a = np.clip(anisotropy, -0.99, 0.99)
    iso = np.abs(a) <= 1e-4
    ax = np.where(iso, alpha, np.where(a > 0.0, alpha * (1.0 - a), alpha / (1.0 + a)))
    ay = np.where(iso, alpha, np.where(a > 0.0, alpha / (1.0 - a), alpha * (1.0 + a)))
    return clamp_alpha(ax), clamp_alpha(ay)


def clamp_alpha(alpha):
    """Cycles' saturate of alpha, and the floor ALPHA_MIN."""
    return np.clip(alpha, ALPHA_MIN, 1.0)


# -- frames -------------------------------------------------------------------------------------
def shading_frame(n: np.ndarray, tangent: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) completing the unit normals n (3, N) to a right-handed frame: x is `tangent`
    (3, N) or (3,) made orthogonal to n (Gram-Schmidt, Cycles' make_orthonormals_tangent), any
    perpendicular where there is no tangent or it is parallel to n."""
    if tangent is None:
        return orthonormal_basis(n)
    t = np.broadcast_to(np.asarray(tangent, dtype=np.float64).reshape(3, -1), n.shape)
    x = t - dot(t, n) * n
    length = np.sqrt(dot(x, x))
    tangent_ok = length > 1e-9
    with np.errstate(invalid="ignore", divide="ignore"):
        if tangent_ok.all():                # no fallback needed: np.where's numbers
            x = x / length
        else:
            x = np.where(tangent_ok, x / length, orthonormal_basis(n)[0])
    return x, cross(n, x)


def to_local(w: np.ndarray, x: np.ndarray, y: np.ndarray, n: np.ndarray) -> np.ndarray:
    return np.stack([dot(w, x), dot(w, y), dot(w, n)])


def to_world(w: np.ndarray, x: np.ndarray, y: np.ndarray, n: np.ndarray) -> np.ndarray:
    return w[0] * x + w[1] * y + w[2] * n


# -- the distributions ------------------------------------------------------------------------
def slope_term(w: np.ndarray, ax, ay) -> np.ndarray:
    """alpha^2 tan^2(theta) of direction w in the anisotropic case: (ax^2 x^2 + ay^2 y^2) / z^2."""
    with np.errstate(divide="ignore", invalid="ignore"):
        s = ((ax * w[0]) ** 2 + (ay * w[1]) ** 2) / (w[2] * w[2])
    return np.where(w[2] != 0.0, s, np.inf)


def ggx_d(h: np.ndarray, ax, ay) -> np.ndarray:
    """GGX normal distribution D(h) (Walter et al. 2007; anisotropic: Heitz 2014 eq. 85), h in
    the upper hemisphere; 0 below."""
    t = (h[0] / ax) ** 2 + (h[1] / ay) ** 2 + h[2] * h[2]
    with np.errstate(divide="ignore"):                  # t = 0 only for h = 0: below, D = 0
        return np.where(h[2] > 0.0, 1.0 / (np.pi * ax * ay * t * t), 0.0)


def ggx_lambda(w: np.ndarray, ax, ay) -> np.ndarray:
    """Smith's Lambda of GGX (Heitz 2014 eq. 72): (sqrt(1 + alpha^2 tan^2) - 1) / 2."""
    return 0.5 * (np.sqrt(1.0 + slope_term(w, ax, ay)) - 1.0)


def beckmann_d(h: np.ndarray, ax, ay) -> np.ndarray:
    """Beckmann normal distribution D(h) (Heitz 2014 eq. 84)."""
    z2 = h[2] * h[2]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d = np.exp(-((h[0] / ax) ** 2 + (h[1] / ay) ** 2) / z2) / (np.pi * ax * ay * z2 * z2)
    return np.where(h[2] > 0.0, np.nan_to_num(d), 0.0)


def erf(x: np.ndarray) -> np.ndarray:
    """The error function to 1.2e-7 (Numerical Recipes' erfc by Chebyshev fit), vectorised."""
    z = np.abs(x)
    t = 1.0 / (1.0 + 0.5 * z)
    poly = (-z * z - 1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 + t * (
        -0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 + t * (
            -0.82215223 + t * 0.17087277)))))))))
    return np.copysign(1.0 - t * np.exp(poly), x)


def beckmann_lambda(w: np.ndarray, ax, ay) -> np.ndarray:
    """Smith's Lambda of Beckmann, exact (Heitz 2014 eq. 80): (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)),
    a = 1 / (alpha tan).  (Cycles uses Walter's rational fit of it, within 0.3 %.)"""
    s = slope_term(w, ax, ay)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        a = 1.0 / np.sqrt(s)
        lam = 0.5 * (erf(a) - 1.0) + np.exp(-a * a) / (2.0 * a * SQRT_PI)
    return np.where(s > 0.0, np.where(np.isfinite(lam), np.maximum(lam, 0.0), np.inf * (s > 0)), 0.0)


D = {GGX: ggx_d, BECKMANN: beckmann_d}
LAMBDA = {GGX: ggx_lambda, BECKMANN: beckmann_lambda}


def g1(w, ax, ay, distribution=GGX):
    """Smith's masking G1(w) = 1 / (1 + Lambda(w)) for directions above the surface."""
    return np.where(w[2] > 0.0, 1.0 / (1.0 + LAMBDA[distribution](w, ax, ay)), 0.0)


def g2(wo, wi, ax, ay, distribution=GGX):
    """Height-correlated masking-shadowing 1 / (1 + Lambda(wo) + Lambda(wi)) (Cycles >= 3.5)."""
    lam = LAMBDA[distribution]
    return np.where((wo[2] > 0.0) & (wi[2] > 0.0), 1.0 / (1.0 + lam(wo, ax, ay) + lam(wi, ax, ay)), 0.0)


def g2_separable(wo, wi, ax, ay, distribution=GGX):
    """Separable G1(wo) G1(wi) (Blender 3.4's Principled v1)."""
    return g1(wo, ax, ay, distribution) * g1(wi, ax, ay, distribution)


# -- visible normals --------------------------------------------------------------------------
def ggx_sample_vndf(wo: np.ndarray, ax, ay, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """A microfacet normal h (3, N) drawn with density D_wo(h) = G1(wo) max(0, wo.h) D(h) / wo_z,
    by Heitz 2018: stretch wo to the alpha = 1 configuration, sample the projected hemisphere
    there, unstretch the normal."""
    v = normalize(np.stack([ax * wo[0], ay * wo[1], wo[2]]))
    lensq = v[0] * v[0] + v[1] * v[1]
    tilted = lensq > 1e-14
    inv = 1.0 / np.sqrt(np.where(tilted, lensq, 1.0))
    t1 = np.where(tilted, np.stack([-v[1] * inv, v[0] * inv, np.zeros_like(lensq)]),
                  np.array([1.0, 0.0, 0.0])[:, None])
    t2 = cross(v, t1)
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + v[2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * p2
    pz = np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))
    nh = p1 * t1 + p2 * t2 + pz * v
    return normalize(np.stack([ax * nh[0], ay * nh[1], np.maximum(0.0, nh[2])]))


def _erfinv(y: np.ndarray) -> np.ndarray:
    """Inverse of `erf` on (-1, 1): Giles' single-precision start, then Newton steps on `erf`."""
    y = np.clip(y, -1.0 + 1e-15, 1.0 - 1e-15)
    w = -np.log((1.0 - y) * (1.0 + y))
    small = w < 5.0
    ws, wl = w - 2.5, np.sqrt(w) - 3.0
    ps = 2.81022636e-08
    for c in (3.43273939e-07, -3.5233877e-06, -4.39150654e-06, 0.00021858087, -0.00125372503,
              -0.00417768164, 0.246640727, 1.50140941):
        ps = c + ps * ws
    pl = -0.000200214257
    for c in (0.000100950558, 0.00134934322, -0.00367342844, 0.00573950773, -0.0076224613,
              0.00943887047, 1.00167406, 2.83297682):
        pl = c + pl * wl
    x = np.where(small, ps, pl) * y
    for _ in range(2):
        x = x - (erf(x) - y) / (2.0 / SQRT_PI * np.exp(-x * x))
    return x


def beckmann_sample_vndf(wo: np.ndarray, ax, ay, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """A Beckmann microfacet normal with density D_wo(h), by Heitz & d'Eon 2014: stretch wo, draw
    the slope x from the visible-slope CDF 1 + erf(x) + K exp(-x^2) (K = tan(theta) / sqrt(pi),
    x <= cot(theta); solved by bisection) and the slope y as erfinv(2 u2 - 1), rotate, unstretch."""
    v = normalize(np.stack([ax * wo[0], ay * wo[1], wo[2]]))
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - v[2] * v[2]))
    tilted = sin_t > 1e-7
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_phi = np.where(tilted, v[0] / sin_t, 1.0)
        sin_phi = np.where(tilted, v[1] / sin_t, 0.0)
        k = np.where(tilted, sin_t / (v[2] * SQRT_PI), 0.0)
        cot = np.where(tilted, v[2] / sin_t, np.inf)
    hi = np.minimum(cot, 8.0)
    lo = np.full_like(hi, -8.0)

    def cdf(x):
        return 1.0 + erf(x) + k * np.exp(-x * x)
    target = u1 * cdf(hi)
    for _ in range(48):                       # bisection to 2^-48 of the bracket: exact in float64 terms
        mid = 0.5 * (lo + hi)
        below = cdf(mid) < target
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    sx = 0.5 * (lo + hi)
    sy = _erfinv(2.0 * u2 - 1.0)
    rx = cos_phi * sx - sin_phi * sy
    ry = sin_phi * sx + cos_phi * sy
    return normalize(np.stack([-rx * ax, -ry * ay, np.ones_like(rx)]))


SAMPLE_VNDF = {GGX: ggx_sample_vndf, BECKMANN: beckmann_sample_vndf}


def vndf_pdf(wo, h, ax, ay, distribution=GGX) -> np.ndarray:
    """D_wo(h) = G1(wo) max(0, wo.h) D(h) / wo_z, the density of the sampled normals."""
    with np.errstate(divide="ignore", invalid="ignore"):
        p = g1(wo, ax, ay, distribution) * np.maximum(dot(wo, h), 0.0) * D[distribution](h, ax, ay) / wo[2]
    return np.where(wo[2] > 0.0, p, 0.0)
