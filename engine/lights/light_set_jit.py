"""engine/lights/light_set.py's `LightSet.shadow_rays` compiled with numba: each shadow ray's origin,
direction and length in one loop over the samples, instead of a take per input and a pass per
operation; and the tail of `LightSet.sample` (the pdf times the pick's pmf and the group's share,
the offset off the light, the sides) in one loop (`finish_sample`).  The float64 operations are those of the NumPy path in the same order (+, -, *, /, sqrt,
copysign), so the rays are the same bit for bit (tests/lights/test_light_set_jit.py).  Imported
only through engine/core/backend.py's choice (it imports numba)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from ..core.kernel_inputs import contiguous

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _shadow_rays(valid, x, lift, ng, cos_ly, offset, point, normal, distance, w, raised, amount, s,
                 origin, direction, length):
    for r in range(valid.shape[0]):
        i = valid[r]
        o0 = x[0, i] + lift[i] * ng[0, i]
        o1 = x[1, i] + lift[i] * ng[1, i]
        o2 = x[2, i] + lift[i] * ng[2, i]
        if raised:
            o0, o1, o2 = o0 + amount[i] * s[0, i], o1 + amount[i] * s[1, i], o2 + amount[i] * s[2, i]
        origin[0, r], origin[1, r], origin[2, r] = o0, o1, o2
        if np.isfinite(distance[i]):
            pull = np.copysign(1.0, cos_ly[i]) * offset[i]
            s0 = point[0, i] - pull * normal[0, i] - o0
            s1 = point[1, i] - pull * normal[1, i] - o1
            s2 = point[2, i] - pull * normal[2, i] - o2
            d = np.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
            length[r] = d
            direction[0, r], direction[1, r], direction[2, r] = s0 / d, s1 / d, s2 / d
        else:
            length[r] = np.inf
            direction[0, r], direction[1, r], direction[2, r] = w[0, i], w[1, i], w[2, i]


@jit
def _maximum(a, b):
    """np.maximum of two numbers (NaN if either is)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b


@jit
def _finish_sample(pdf, pmf, share, point, light, one_sided_of, scale, pdf_out, offset, one_sided):
    for i in range(pdf.shape[0]):
        pdf_out[i] = pdf[i] * pmf[i] * share
        offset[i] = scale * _maximum(_maximum(np.abs(point[0, i]), np.abs(point[1, i])), np.abs(point[2, i]))
        one_sided[i] = one_sided_of[light[i]]


def finish_sample(pdf, pmf, share, point, light, one_sided_of, scale):
    """LightSet.sample's tail: (pdf * pmf * share, scale * max_abs3(point), one_sided_of.take(light))."""
    n = len(pdf)
    pdf_out, offset, one_sided = np.empty(n), np.empty(n), np.empty(n, dtype=np.bool_)
    _finish_sample(contiguous(pdf), contiguous(pmf), float(share), contiguous(point),
                   np.ascontiguousarray(light, dtype=np.int64), np.ascontiguousarray(one_sided_of, dtype=np.bool_),
                   float(scale), pdf_out, offset, one_sided)
    return pdf_out, offset, one_sided


def shadow_rays(ls, valid, x, lift, ng, cos_ly, raised=None):
    """LightSet.shadow_rays (the same arguments and results)."""
    k = x.shape[1]
    valid = np.arange(k, dtype=np.int64) if valid is None else np.ascontiguousarray(valid, dtype=np.int64)
    v = len(valid)
    origin, direction, length = np.empty((3, v)), np.empty((3, v)), np.empty(v)
    amount, s = (np.zeros(1), np.zeros((3, 1))) if raised is None else (contiguous(raised[0]), contiguous(raised[1]))
    _shadow_rays(valid, contiguous(x), contiguous(np.broadcast_to(lift, (k,))), contiguous(ng), contiguous(cos_ly),
                 contiguous(ls.offset), contiguous(ls.point), contiguous(ls.normal), contiguous(ls.distance),
                 contiguous(ls.direction), raised is not None, amount, s, origin, direction, length)
    return origin, direction, length


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes."""
    from types import SimpleNamespace
    x = np.zeros((3, 2))
    ls = SimpleNamespace(offset=np.full(2, 1e-6), point=np.ones((3, 2)), normal=np.ones((3, 2)),
                         distance=np.array([1.0, np.inf]), direction=np.ones((3, 2)))
    shadow_rays(ls, None, x, np.ones(2), x, np.ones(2))
    shadow_rays(ls, np.array([1]), x, np.ones(2), x, np.ones(2), (np.ones(2), x))
    finish_sample(np.ones(2), np.ones(2), 1.0, x, np.zeros(2, np.int64), np.zeros(1, np.bool_), 2.0 ** -20)
