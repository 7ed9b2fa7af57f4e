"""engine/lights/environment.py's PiecewiseConstant2D (the image world's importance sampler) compiled with
numba: `sample` (the row by its marginal, the column in the row, both by binary search) and `pdf`, one loop
over the points instead of two np.searchsorted over the whole tables and some twenty NumPy passes.
Imported only through engine/core/backend.py's choice (it imports numba; kernel name "wavefront");
EnvironmentMap.use_backend hands it to its distribution.

The same operations in the same order and precision: np.searchsorted(side="right") as its binary search
(engine/sampling/search_jit.py) with NumPy's NaN-last order, take's wrap of index -1, np.clip / np.minimum with their NaN rule, and the
float -> int64 cast of engine/materials/textures_jit.py (`_int`), so the values are NumPy's bit for bit
(tests/lights/test_environment_jit.py)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from ..materials.textures_jit import _int
from ..sampling.search_jit import search_right

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

BELOW_ONE = np.nextafter(1.0, 0.0)


@jit
def _clip(x, lo, hi):
    """np.clip of a scalar (NaN stays NaN)."""
    if x != x:
        return x
    return lo if x < lo else (hi if x > hi else x)


@jit
def _sample(marginal, flat, conditional, density, w, h, last_row, u1, u2):
    n = u1.shape[0]
    u_out, v_out, p_out = np.empty(n), np.empty(n), np.empty(n)
    m = marginal.shape[0]
    c = conditional.shape[0]
    for k in range(n):
        a, b = u1[k], u2[k]
        j = min(search_right(marginal, marginal.shape[0], b) - 1, last_row)
        lo = marginal[j if j >= 0 else j + m]
        hi = marginal[j + 1]
        dv = _clip((b - lo) / (hi - lo), 0.0, 1.0)
        i = min(max(search_right(flat, flat.shape[0], j + a) - j * w, 0), w - 1)
        f = j * (w + 1) + i
        lo, hi = conditional[f if f >= 0 else f + c], conditional[f + 1 if f + 1 >= 0 else f + 1 + c]
        span = hi - lo
        du = _clip((a - lo) / (span if span >= 1e-300 or span != span else 1e-300), 0.0, 1.0)
        uu = (i + du) / w
        vv = (j + dv) / h
        u_out[k] = uu if (uu <= BELOW_ONE or uu != uu) else BELOW_ONE
        v_out[k] = vv if (vv <= BELOW_ONE or vv != vv) else BELOW_ONE
        d = j * w + i
        p_out[k] = density[d if d >= 0 else d + density.shape[0]]
    return u_out, v_out, p_out


@jit
def _pdf(density, w, h, u, v):
    n = u.shape[0]
    out = np.empty(n)
    for k in range(n):
        i = min(max(_int(np.floor(u[k] * w)), 0), w - 1)
        j = min(max(_int(np.floor(v[k] * h)), 0), h - 1)
        out[k] = density[j * w + i]
    return out


def sample(dist, u1, u2):
    """PiecewiseConstant2D.sample of `dist`: (u, v, density) from uniforms u1 (the column), u2 (the row)."""
    return _sample(dist.marginal, dist.flat, dist.conditional_flat, dist.density_flat, dist.w, dist.h, dist.last_row,
                   np.ascontiguousarray(u1, np.float64), np.ascontiguousarray(u2, np.float64))


def pdf(dist, u, v):
    """PiecewiseConstant2D.pdf of `dist` at (u, v)."""
    return _pdf(dist.density_flat, dist.w, dist.h, np.ascontiguousarray(u, np.float64),
                np.ascontiguousarray(v, np.float64))


def warm_up() -> None:
    """Compile (or load) both kernels for the types a render passes."""
    from types import SimpleNamespace             # PiecewiseConstant2D(np.ones((2, 4)))'s tables
    conditional = np.tile(np.linspace(0.0, 1.0, 5), (2, 1))
    dist = SimpleNamespace(marginal=np.array([0.0, 0.5, 1.0]), flat=(np.arange(2)[:, None] + conditional[:, 1:]).ravel(),
                           conditional_flat=conditional.ravel(), density_flat=np.ones(8), w=4, h=2, last_row=1)
    u = np.array([0.25, 0.75])
    sample(dist, u, u)
    pdf(dist, u, u)
