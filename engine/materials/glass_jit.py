"""engine/materials/glass.py's SmoothGlass.sample compiled with numba, for flat shading without a
medium stack (nested dielectrics off): two loops over the hits around the Fresnel reflectance, which
stays NumPy's (Schlick's (1 - cos)^5 is NumPy's power, whose vectorised float64 bits libm's pow does
not give).  Imported only through engine/core/backend.py's choice (it imports numba).

* `cosines`: the ray's cosine with the oriented normal, entering or leaving, eta = n1 / n2 of the
  material's IOR and Snell's law (specular.refract_cos): cos_i, cos_t, eta, tir.
* `directions`: u_lobe < R reflects (specular.reflect), else the ray refracts (specular.refract,
  normalised); pdf R or 1 - R and the lobe's flags.

The same float64 operations in the same order as the NumPy code (+ - * / sqrt, no fused
multiply-adds): the same directions and pdfs bit for bit (tests/materials/test_glass_jit.py)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _maximum0(x):
    """np.maximum(0.0, x) (NaN stays NaN)."""
    if x != x:
        return x
    return x if x > 0.0 else 0.0


@jit
def _cosines(wo, normal, material, ior, cos_i, cos_t, eta, tir):
    for j in range(material.shape[0]):
        cos_in = -wo[0, j] * normal[0, j] + -wo[1, j] * normal[1, j] + -wo[2, j] * normal[2, j]
        c = abs(cos_in)
        n2 = ior[material[j]]
        e = 1.0 / n2 if cos_in < 0.0 else n2
        sin2_t = e * e * _maximum0(1.0 - c * c)
        tir[j] = sin2_t >= 1.0
        cos_t[j] = np.sqrt(_maximum0(1.0 - sin2_t))
        cos_i[j], eta[j] = c, e


@jit
def _directions(wo, n, cos_i, cos_t, eta, fresnel, u_lobe, reflected_flag, transmitted_flag, wi, pdf, flags):
    for j in range(eta.shape[0]):
        d0, d1, d2 = -wo[0, j], -wo[1, j], -wo[2, j]
        n0, n1, n2 = n[0, j], n[1, j], n[2, j]
        r = fresnel[j]
        if u_lobe[j] < r:
            twice = 2.0 * (d0 * n0 + d1 * n1 + d2 * n2)
            wi[0, j], wi[1, j], wi[2, j] = d0 - twice * n0, d1 - twice * n1, d2 - twice * n2
            pdf[j], flags[j] = r, reflected_flag
        else:
            e = eta[j]
            along = e * cos_i[j] - cos_t[j]
            t0, t1, t2 = e * d0 + along * n0, e * d1 + along * n1, e * d2 + along * n2
            length = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
            wi[0, j], wi[1, j], wi[2, j] = t0 / length, t1 / length, t2 / length
            pdf[j], flags[j] = 1.0 - r, transmitted_flag


def cosines(wo, normal, material, ior):
    """(cos_i, cos_t, eta, tir) of SmoothGlass.sample at hits with directions to the viewer wo and
    oriented geometric normals `normal` (rows), materials `material` and the IOR of each material."""
    m = len(material)
    cos_i, cos_t, eta, tir = np.empty(m), np.empty(m), np.empty(m), np.empty(m, np.bool_)
    _cosines(wo, normal, np.ascontiguousarray(material, np.int64), ior, cos_i, cos_t, eta, tir)
    return cos_i, cos_t, eta, tir


def directions(wo, n, cos_i, cos_t, eta, fresnel, u_lobe, reflected_flag, transmitted_flag):
    """(wi rows, pdf, flags int8) of SmoothGlass.sample from cosines' values and the reflectance."""
    m = len(eta)
    wi, pdf, flags = np.empty((3, m)), np.empty(m), np.empty(m, np.int8)
    _directions(wo, n, cos_i, cos_t, eta, np.ascontiguousarray(fresnel, np.float64),
                np.ascontiguousarray(u_lobe, np.float64), np.int8(reflected_flag), np.int8(transmitted_flag),
                wi, pdf, flags)
    return wi, pdf, flags


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes: rows whole and sliced."""
    rows = np.zeros((3, 4))
    rows[2] = 1.0
    material, ior, u = np.zeros(2, np.int64), np.array([1.5]), np.full(2, 0.5)
    for wo, n in ((rows[:, :2].copy(), rows[:, :2].copy()), (rows[:, 1:3], rows[:, 1:3])):
        cos_i, cos_t, eta, tir = cosines(wo, n, material, ior)
        directions(wo, n, cos_i, cos_t, eta, np.full(2, 0.04), u, 1, 2)
