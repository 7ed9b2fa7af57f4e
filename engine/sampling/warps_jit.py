"""engine/sampling/warps.py's `uniform_cone` compiled with numba, with the cones' axes and widths read
by index (a sun's light samples: engine/lights/distant.py SunLights.sample_li): the directions in one
loop over the samples instead of some twenty-five NumPy passes and two takes.  Imported only through
engine/core/backend.py's choice (it imports numba; kernel name "wavefront").

The float32 cos and sin of the angle stay NumPy's (warps.circle_float32): NumPy's vectorised float32
trigonometry and libm's cosf / sinf, which numba calls, differ in the last bit.  The rest are the
same float64 operations in the same order (orthonormal_basis' frame, unit_circle's renormalisation,
np.maximum's NaN rule; no fused multiply-adds), so the directions are NumPy's bit for bit
(tests/sampling/test_warps_jit.py)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from .warps import circle_float32

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _uniform_cone(u1, c32, s32, idx, axis, one_minus_cos, out):
    for i in range(u1.shape[0]):
        k = idx[i]
        cos_t = 1.0 - u1[i] * one_minus_cos[k]
        q = 1.0 - cos_t * cos_t
        sin_t = np.sqrt(q if q != q or q > 0.0 else 0.0)          # np.maximum(q, 0.0): NaN stays NaN
        x, y, z = axis[0, k], axis[1, k], axis[2, k]
        sign = np.copysign(1.0, z)                                  # orthonormal_basis (Duff et al.)
        a = -1.0 / (sign + z)
        b = x * y * a
        t1x, t1y, t1z = 1.0 + sign * x * x * a, sign * b, -sign * x
        t2x, t2y, t2z = b, sign + y * y * a, -y
        c, s = np.float64(c32[i]), np.float64(s32[i])               # unit_circle
        inv = 1.0 / np.sqrt(c * c + s * s)
        c, s = c * inv, s * inv
        out[0, i] = cos_t * x + sin_t * (c * t1x + s * t2x)
        out[1, i] = cos_t * y + sin_t * (c * t1y + s * t2y)
        out[2, i] = cos_t * z + sin_t * (c * t1z + s * t2z)


def uniform_cone_at(u1, u2, idx, axis, one_minus_cos):
    """warps.uniform_cone(u1, u2, axis.take(idx, axis=1), one_minus_cos.take(idx))'s directions (3, N)
    for the uniforms u1, u2 (N,), the cones `idx` (N,) of the unit axis rows `axis` (3, K)."""
    c32, s32 = circle_float32(u2)
    out = np.empty((3, len(c32)))
    _uniform_cone(np.ascontiguousarray(u1, np.float64), c32, s32, np.ascontiguousarray(idx, np.int64),
                  np.ascontiguousarray(axis, np.float64), np.ascontiguousarray(one_minus_cos, np.float64), out)
    return out


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes."""
    uniform_cone_at(np.full(2, 0.5), np.full(2, 0.25), np.zeros(2, np.int64), np.array([[0.0], [0.6], [0.8]]),
                    np.array([1e-3]))
