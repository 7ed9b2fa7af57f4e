"""Sample warps and local frames, vectorised over rays.

Every function takes arrays of uniform numbers in [0, 1) and returns float64 arrays,
so the same code serves the integrator and the chi-square tests.
"""
from __future__ import annotations

import numpy as np

# Largest float64 below 1: uniforms are clamped to it so that no warp sees u == 1.
ONE_MINUS_EPSILON = np.nextafter(1.0, 0.0)


def orthonormal_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangent and bitangent for unit normals n (N, 3): Duff et al. 2017.

    Uses copysign so a normal with z = 0 or -0.0 (every Cornell wall) is safe;
    np.sign would give 0 there and a NaN basis (hard case S2).
    """
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    sign = np.copysign(1.0, z)
    a = -1.0 / (sign + z)
    b = x * y * a
    tangent = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=1)
    bitangent = np.stack([b, sign + y * y * a, -y], axis=1)
    return tangent, bitangent


def cosine_hemisphere(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Cosine-weighted directions about +z (report eq. 2.13b, pdf = cos(theta)/pi).

    The report draws theta = acos(r^(1/(1+n))) with n = 1, i.e. cos(theta) = sqrt(r).
    Written as z = sqrt(1 - u1) with u1 clamped below 1 it never returns z = 0, so
    the pdf is always positive and f*cos/pdf is exactly the albedo (hard case S1).
    """
    u1 = np.minimum(u1, ONE_MINUS_EPSILON)
    z = np.sqrt(1.0 - u1)
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def to_world(local: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Rotate directions given about +z into the frame of each normal."""
    tangent, bitangent = orthonormal_basis(normal)
    return (local[:, 0:1] * tangent + local[:, 1:2] * bitangent + local[:, 2:3] * normal)


def uniform_triangle(u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Barycentrics (b1, b2) uniform over a triangle's area (pdf = 1/A)."""
    s = np.sqrt(u1)
    return s * (1.0 - u2), s * u2


def uniform_sphere(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Directions uniform over the unit sphere (pdf over the sphere's area = 1/A)."""
    z = 1.0 - 2.0 * u1
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
