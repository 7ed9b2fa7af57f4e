"""Sample warps and local frames, vectorised over rays.

Every function takes arrays of uniform numbers in [0, 1) and returns float64 rows
(3, N) (engine/core/vec.py), so the same code serves the integrator and the chi-square tests.
"""
from __future__ import annotations

import numpy as np

# Largest float64 below 1: uniforms are clamped to it so that no warp sees u == 1.
ONE_MINUS_EPSILON = np.nextafter(1.0, 0.0)


def orthonormal_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangent and bitangent rows for unit normal rows n (3, N): Duff et al. 2017.

    Uses copysign so a normal with z = 0 or -0.0 (every Cornell wall) is safe;
    np.sign would give 0 there and a NaN basis (docs/hard-cases.md S2).
    """
    x, y, z = n[0], n[1], n[2]
    sign = np.copysign(1.0, z)
    a = -1.0 / (sign + z)
    b = x * y * a
    tangent = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x])
    bitangent = np.stack([b, sign + y * y * a, -y])
    return tangent, bitangent


def unit_circle(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(cos phi, sin phi) for phi = 2 pi u, as float64 of exactly unit length.

    The trigonometry runs in float32 (NumPy vectorises float32 sin/cos, about 10x
    faster than float64 here); the float64 pair is then renormalised, so only the
    angle carries float32 error (~1e-7 rad), not the length.
    """
    c32, s32 = circle_float32(u)
    c = c32.astype(np.float64)
    s = s32.astype(np.float64)
    inv = 1.0 / np.sqrt(c * c + s * s)
    return c * inv, s * inv


def circle_float32(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """unit_circle's float32 cos and sin of phi = 2 pi u, before the renormalisation.  NumPy's own
    vectorised float32 cos / sin: a compiled twin takes these (libm's cosf / sinf give other bits)."""
    phi = (2.0 * np.pi * u).astype(np.float32)
    return np.cos(phi), np.sin(phi)


def _cosine_local(u1: np.ndarray, u2: np.ndarray):
    """Components (x, y, z) of cosine-weighted directions about +z (eq. 2.13b)."""
    u1 = np.minimum(u1, ONE_MINUS_EPSILON)
    r = np.sqrt(u1)
    c, s = unit_circle(u2)
    return r * c, r * s, np.sqrt(1.0 - u1)


def cosine_hemisphere(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Cosine-weighted direction rows about +z (report eq. 2.13b, pdf = cos(theta)/pi).

    The report draws theta = acos(r^(1/(1+n))) with n = 1, i.e. cos(theta) = sqrt(r).
    Written as z = sqrt(1 - u1) with u1 clamped below 1 it never returns z = 0, so
    the pdf is always positive and f*cos/pdf is exactly the albedo (docs/hard-cases.md S1).
    """
    return np.stack(_cosine_local(u1, u2))


def to_world(local: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Rotate direction rows given about +z into the frame of each normal (rows)."""
    tangent, bitangent = orthonormal_basis(normal)
    return local[0] * tangent + local[1] * bitangent + local[2] * normal


def cosine_directions(u1: np.ndarray, u2: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """to_world(cosine_hemisphere(u1, u2), normal), the diffuse bounce (eq. 2.13-2.14),
    written out per component: no intermediate tangent and bitangent arrays."""
    lx, ly, lz = _cosine_local(u1, u2)
    x, y, z = normal[0], normal[1], normal[2]
    sign = np.copysign(1.0, z)                      # the frame of orthonormal_basis
    a = -1.0 / (sign + z)
    b = x * y * a
    sx = sign * x
    out = np.empty((3, len(lx)))
    # tangent = (1 + sign x^2 a, sign b, -sign x), bitangent = (b, sign + y^2 a, -y)
    out[0] = lx * (1.0 + sx * x * a) + ly * b + lz * x
    out[1] = lx * (sign * b) + ly * (sign + y * y * a) + lz * y
    out[2] = lz * z - lx * sx - ly * y
    return out


def uniform_triangle(u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Barycentrics (b1, b2) uniform over a triangle's area (pdf = 1/A)."""
    s = np.sqrt(u1)
    return s * (1.0 - u2), s * u2


def uniform_sphere(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Direction rows uniform over the unit sphere (pdf over the sphere's area = 1/A)."""
    z = 1.0 - 2.0 * u1
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    c, s = unit_circle(u2)
    return np.stack([r * c, r * s, z])


def uniform_cone(u1: np.ndarray, u2: np.ndarray, axis: np.ndarray, one_minus_cos_max: np.ndarray):
    """Direction rows uniform over the cone of directions within theta_max of the unit rows
    `axis` (pdf 1 / (2 pi (1 - cos theta_max))), and the cosine of each to its axis.  The caller
    passes 1 - cos theta_max in a form without cancellation for narrow cones."""
    cos_t = 1.0 - u1 * one_minus_cos_max
    sin_t = np.sqrt(np.maximum(1.0 - cos_t * cos_t, 0.0))
    t1, t2 = orthonormal_basis(axis)
    c, s = unit_circle(u2)
    return cos_t * axis + sin_t * (c * t1 + s * t2), cos_t
