"""Fresnel reflectance of a smooth dielectric interface (report 2.5.4): the fraction R of light
it reflects, T = 1 - R, for the cosines of the incident and the refracted ray (cos_t and the
total-internal-reflection mask from Snell's law, engine/materials/specular.py).

``eta`` = n1 / n2, the IOR the light comes from over the one it goes into.
"""
from __future__ import annotations

import numpy as np

# Interfaces closer to index-matched than this pass light straight through, as
# Cycles does (docs/hard-cases.md S5): Schlick would otherwise reflect 99 % at grazing angles.
INDEX_MATCHED = 1e-4


def fresnel_schlick(cos_i: np.ndarray, cos_t: np.ndarray, eta: np.ndarray,
                    tir: np.ndarray) -> np.ndarray:
    """Schlick's approximation (eq. 2.17) of the reflected fraction R; T = 1 - R.

    R0 = ((n1 - n2)/(n1 + n2))^2 depends only on the ratio eta = n1/n2.  The cosine is
    taken on the less dense side (cos_t when leaving glass), so R rises continuously
    to 1 at the critical angle instead of jumping from 0.04 (docs/hard-cases.md S4).
    """
    r0 = ((eta - 1.0) / (eta + 1.0)) ** 2
    cos = np.where(eta > 1.0, cos_t, cos_i)
    r = r0 + (1.0 - r0) * (1.0 - cos) ** 5
    r = np.where(tir, 1.0, r)
    return np.where(np.abs(eta - 1.0) < INDEX_MATCHED, 0.0, r)


def fresnel_exact(cos_i: np.ndarray, cos_t: np.ndarray, eta: np.ndarray,
                  tir: np.ndarray) -> np.ndarray:
    """Unpolarised dielectric Fresnel reflectance, as Cycles' sharp glass uses."""
    with np.errstate(divide="ignore", invalid="ignore"):
        r_par = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
        r_perp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
        r = 0.5 * (r_par * r_par + r_perp * r_perp)
    r = np.where(tir, 1.0, r)
    r = np.where(np.isfinite(r), r, 1.0)  # cos_i = cos_t = 0: grazing, all reflected
    return np.where(np.abs(eta - 1.0) < INDEX_MATCHED, 0.0, np.clip(r, 0.0, 1.0))


FRESNEL = {"schlick": fresnel_schlick, "exact": fresnel_exact}     # RenderSettings.fresnel
