"""engine/materials/lambert.py's sampling compiled with numba: Lambertian.sample's cosine-weighted
direction (engine/sampling/warps.py cosine_directions: unit_circle's renormalisation, the local
direction and the frame of orthonormal_basis) and its pdf (Lambertian.pdf) in one loop over the hits,
instead of some twenty NumPy calls.  Imported only through engine/core/backend.py's choice (it imports
numba).

The float32 cos and sin of the angle stay NumPy's (warps.circle_float32): NumPy's vectorised float32
trigonometry and libm's cosf / sinf, which numba calls, differ in the last bit.  The rest are the
same float64 operations in the same order (+ - * / sqrt, no fused multiply-adds), so the directions
and pdfs are NumPy's bit for bit (tests/materials/test_lambert_jit.py)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from ..sampling.warps import ONE_MINUS_EPSILON, circle_float32

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _direction(v, c32, s32, x, y, z, one_minus_epsilon, inv_pi):
    """One hit's cosine-weighted direction (w0, w1, w2) about the unit normal (x, y, z) and its pdf,
    from its uniform u1 = v and the float32 cos and sin c32, s32 of 2 pi u2."""
    if not v != v and v > one_minus_epsilon:                # np.minimum (NaN stays NaN)
        v = one_minus_epsilon
    r = np.sqrt(v)
    c, s = np.float64(c32), np.float64(s32)
    inv = 1.0 / np.sqrt(c * c + s * s)
    lx, ly, lz = r * (c * inv), r * (s * inv), np.sqrt(1.0 - v)
    sign = np.copysign(1.0, z)
    a = -1.0 / (sign + z)
    b = x * y * a
    sx = sign * x
    w0 = lx * (1.0 + sx * x * a) + ly * b + lz * x
    w1 = lx * (sign * b) + ly * (sign + y * y * a) + lz * y
    w2 = lz * z - lx * sx - ly * y
    cos = w0 * x + w1 * y + w2 * z                           # vec.dot(wi, n)
    if cos != cos:                                           # np.maximum(cos, 0.0): NaN stays NaN
        return w0, w1, w2, cos * inv_pi
    return w0, w1, w2, (cos if cos > 0.0 else 0.0) * inv_pi


@jit
def _sample(u1, c32, s32, n, one_minus_epsilon, inv_pi, wi, pdf):
    for i in range(u1.shape[0]):
        wi[0, i], wi[1, i], wi[2, i], pdf[i] = _direction(u1[i], c32[i], s32[i], n[0, i], n[1, i], n[2, i],
                                                          one_minus_epsilon, inv_pi)


@jit
def _sample_at(idx, u1, c32, s32, n, one_minus_epsilon, inv_pi, wi, pdf):
    for k in range(idx.shape[0]):
        i = idx[k]
        wi[0, i], wi[1, i], wi[2, i], pdf[k] = _direction(u1[i], c32[k], s32[k], n[0, i], n[1, i], n[2, i],
                                                          one_minus_epsilon, inv_pi)


def sample(u1, u2, n):
    """(wi rows, pdf) of Lambertian.sample for the uniforms u1, u2 (N,) about the unit normals n (3, N)."""
    c32, s32 = circle_float32(u2)
    m = len(c32)
    wi, pdf = np.empty((3, m)), np.empty(m)
    _sample(np.ascontiguousarray(u1, np.float64), c32, s32, n, ONE_MINUS_EPSILON, 1.0 / np.pi, wi, pdf)
    return wi, pdf


def sample_at(idx, u1, u2, n, wi):
    """`sample` at the hits idx (K,) of u1, u2 (N,) and n (3, N), the directions written into wi[:, idx]
    (wi (3, N)) without gathering the hits' values first; returns their pdfs (K,)."""
    idx = np.ascontiguousarray(idx, dtype=np.int64)
    c32, s32 = circle_float32(np.asarray(u2).take(idx))
    pdf = np.empty(len(idx))
    _sample_at(idx, np.ascontiguousarray(u1, np.float64), c32, s32, n, ONE_MINUS_EPSILON, 1.0 / np.pi, wi, pdf)
    return pdf


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes: normals as whole rows and as a
    slice of the wavefront's rows."""
    u = np.full(2, 0.5)
    rows = np.zeros((3, 4))
    rows[2] = 1.0
    sample(u, u, rows[:, :2].copy())
    sample(u, u, rows[:, 1:3])
    for normals in (rows[:, :2].copy(), rows[:, 1:3]):
        sample_at(np.array([1]), u, u, normals, np.empty((3, 2)))
