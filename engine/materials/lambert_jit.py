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
def _sample(u1, c32, s32, n, one_minus_epsilon, inv_pi, wi, pdf):
    for i in range(u1.shape[0]):
        v = u1[i]
        if not v != v and v > one_minus_epsilon:            # np.minimum (NaN stays NaN)
            v = one_minus_epsilon
        r = np.sqrt(v)
        c, s = np.float64(c32[i]), np.float64(s32[i])
        inv = 1.0 / np.sqrt(c * c + s * s)
        lx, ly, lz = r * (c * inv), r * (s * inv), np.sqrt(1.0 - v)
        x, y, z = n[0, i], n[1, i], n[2, i]
        sign = np.copysign(1.0, z)
        a = -1.0 / (sign + z)
        b = x * y * a
        sx = sign * x
        w0 = lx * (1.0 + sx * x * a) + ly * b + lz * x
        w1 = lx * (sign * b) + ly * (sign + y * y * a) + lz * y
        w2 = lz * z - lx * sx - ly * y
        wi[0, i], wi[1, i], wi[2, i] = w0, w1, w2
        cos = w0 * x + w1 * y + w2 * z                       # vec.dot(wi, n)
        if cos != cos:                                       # np.maximum(cos, 0.0): NaN stays NaN
            pdf[i] = cos * inv_pi
        else:
            pdf[i] = (cos if cos > 0.0 else 0.0) * inv_pi


def sample(u1, u2, n):
    """(wi rows, pdf) of Lambertian.sample for the uniforms u1, u2 (N,) about the unit normals n (3, N)."""
    c32, s32 = circle_float32(u2)
    m = len(c32)
    wi, pdf = np.empty((3, m)), np.empty(m)
    _sample(np.ascontiguousarray(u1, np.float64), c32, s32, n, ONE_MINUS_EPSILON, 1.0 / np.pi, wi, pdf)
    return wi, pdf


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes: normals as whole rows and as a
    slice of the wavefront's rows."""
    u = np.full(2, 0.5)
    rows = np.zeros((3, 4))
    rows[2] = 1.0
    sample(u, u, rows[:, :2].copy())
    sample(u, u, rows[:, 1:3])
