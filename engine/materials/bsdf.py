"""Scattering at perfect mirrors and smooth glass (report 2.5.3, 2.5.4).

Directions are unit vector rows (3, N) (engine/core/vec.py); ``normal`` always faces the incoming ray
(dot(d, n) <= 0), so cos_i = -dot(d, n) >= 0.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import dot, normalize

# Interfaces closer to index-matched than this pass light straight through, as
# Cycles does (hard case S5): Schlick would otherwise reflect 99 % at grazing angles.
INDEX_MATCHED = 1e-4




def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror direction r = i - 2 (i . n) n (eq. 2.20c)."""
    return d - 2.0 * dot(d, n) * n


def refract_cos(cos_i: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos(theta_t) by Snell's law (eq. 2.21) and the total-internal-reflection mask.

    eta = n1 / n2.  Where sin^2(theta_t) >= 1 the ray is totally reflected; cos_t is
    returned as 0 there instead of the NaN of a negative square root (hard case S4).
    """
    sin2_t = eta * eta * np.maximum(0.0, 1.0 - cos_i * cos_i)
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    return cos_t, tir


def refract(d: np.ndarray, n: np.ndarray, cos_i: np.ndarray, cos_t: np.ndarray,
            eta: np.ndarray) -> np.ndarray:
    """Transmitted direction t = eta i + (eta cos_i - cos_t) n (eq. 2.22-2.24)."""
    t = eta * d + (eta * cos_i - cos_t) * n
    return normalize(t)


def fresnel_schlick(cos_i: np.ndarray, cos_t: np.ndarray, eta: np.ndarray,
                    tir: np.ndarray) -> np.ndarray:
    """Schlick's approximation (eq. 2.17) of the reflected fraction R; T = 1 - R.

    R0 = ((n1 - n2)/(n1 + n2))^2 depends only on the ratio eta = n1/n2.  The cosine is
    taken on the less dense side (cos_t when leaving glass), so R rises continuously
    to 1 at the critical angle instead of jumping from 0.04 (hard case S4).
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


FRESNEL = {"schlick": fresnel_schlick, "exact": fresnel_exact}
