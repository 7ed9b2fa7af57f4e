"""Directions of perfect specular scattering (report 2.5.3, 2.5.4): the mirror direction, Snell's
law and the refracted direction, and the normal a specular lobe uses under shading normals.

Directions are unit vector rows (3, N) (engine/core/vec.py); ``d`` is the direction the light
travels in towards the surface and ``n`` faces it (dot(d, n) <= 0), so cos_i = -dot(d, n) >= 0.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import dot, normalize
from ..geometry.shading_normals import ensure_valid_reflection


def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror direction r = i - 2 (i . n) n (eq. 2.20c)."""
    return d - 2.0 * dot(d, n) * n


def refract_cos(cos_i: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos(theta_t) by Snell's law (eq. 2.21) and the total-internal-reflection mask.

    eta = n1 / n2.  Where sin^2(theta_t) >= 1 the ray is totally reflected; cos_t is
    returned as 0 there instead of the NaN of a negative square root (docs/hard-cases.md S4).
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


def specular_normal(si) -> np.ndarray:
    """The normal a delta lobe reflects about at the hits `si` (an engine/materials/protocol.py
    ShadingPoint): the shading normal, bent under smooth shading just enough that the mirror
    direction clears the geometric surface (Cycles' valid-reflection normal,
    engine/geometry/shading_normals.py)."""
    return ensure_valid_reflection(si.ng, si.wo, si.n) if si.smooth else si.n


def specular_normal_at(si) -> np.ndarray:
    """specular_normal once per hit set (ShadingPoint.memo): the normal a microfacet lobe's frame is
    built on.  Cycles bends the closure normal of its Glossy, Metallic, Glass and Refraction BSDFs
    and of the Principled BSDF's specular layers this way (maybe_ensure_valid_specular_reflection in
    svm_node_closure_bsdf; its diffuse, sheen and Oren-Nayar closures keep the shading normal), so a
    silhouette's shading normal that faces away from the viewer still gives a lobe above it."""
    return si.memo("specular_normal", specular_normal)
