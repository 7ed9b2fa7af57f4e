"""engine/geometry/shading_normals.py's per-hit passes compiled with numba, one loop each instead of a few
dozen NumPy passes: the Phong normals at hits and the shadow-terminator lift.  Imported only through
engine/core/backend.py's choice (it imports numba; kernel name "wavefront").

* `shading`: SmoothNormals.shading (interpolate_rows' (w0 c0 + u c1) + v c2, its length and the
  geometric normal where the corners cancel) per hit, flat hits keeping the geometric normal;
* `terminator_lift`: SceneGeometry.terminator_lift, SmoothNormals.terminator_lift and
  smooth_surface_offset (the parabola, the corners' tangent-plane bounds for both signs) per hit of a
  span; flat, non-triangle or cutoff-0 hits get 0.

The float operations are the NumPy code's, in its order and precision (engine/core/vec.py dot is
(x + y) + z), np.maximum / np.minimum with their NaN rule: the same arrays bit for bit
(tests/geometry/test_shading_normals_jit.py)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

TRIANGLE = 1            # engine/geometry/scene_geometry.py's kind of a triangle hit


@jit
def _max(a, b):
    """np.maximum of two scalars (NaN wins; of two equal ones b, as NumPy: np.maximum(-0.0, 0.0) is 0.0)."""
    return a if (a > b or a != a) else b


@jit
def _min(a, b):
    """np.minimum of two scalars (NaN wins; of two equal ones b, as NumPy)."""
    return a if (a < b or a != a) else b


@jit
def _dot3(ax, ay, az, bx, by, bz):
    return ax * bx + ay * by + az * bz


# -- Phong normals at hits ----------------------------------------------------------------------------
@jit
def _shading(prim, u, v, geometric, index, corners):
    m = prim.shape[0]
    out = np.empty((3, m))
    for i in range(m):
        r = index[prim[i]]
        gx, gy, gz = geometric[0, i], geometric[1, i], geometric[2, i]
        if r < 0:
            out[0, i], out[1, i], out[2, i] = gx, gy, gz
            continue
        ui, vi = u[i], v[i]
        w0 = 1.0 - ui - vi
        nx = w0 * corners[r, 0, 0] + ui * corners[r, 1, 0] + vi * corners[r, 2, 0]
        ny = w0 * corners[r, 0, 1] + ui * corners[r, 1, 1] + vi * corners[r, 2, 1]
        nz = w0 * corners[r, 0, 2] + ui * corners[r, 1, 2] + vi * corners[r, 2, 2]
        length = np.sqrt(_dot3(nx, ny, nz, nx, ny, nz))
        if length > 1e-9:
            s = _max(length, 1e-300)
            out[0, i], out[1, i], out[2, i] = nx / s, ny / s, nz / s
        else:
            out[0, i], out[1, i], out[2, i] = gx, gy, gz
    return out


def shading(prim, u, v, geometric, index, corners):
    """SmoothNormals.shading: rows (3, M) of the hits (prim, u, v) with geometric normals `geometric`;
    index: the smooth row of each triangle (-1: flat), corners (count, 3, 3)."""
    return _shading(np.ascontiguousarray(prim, np.int64), np.ascontiguousarray(u, np.float64),
                    np.ascontiguousarray(v, np.float64), np.ascontiguousarray(geometric, np.float64), index, corners)


# -- the normal a mirror reflects about (Cycles 3.x's ensure_valid_reflection) -------------------------
@jit
def _valid_reflection(ng, i, n, out):
    bad = 0
    for h in range(n.shape[1]):
        gx, gy, gz = ng[0, h], ng[1, h], ng[2, h]
        ix_, iy_, iz_ = i[0, h], i[1, h], i[2, h]
        nx, ny, nz = n[0, h], n[1, h], n[2, h]
        out[0, h], out[1, h], out[2, h] = nx, ny, nz
        iz = _dot3(ix_, iy_, iz_, gx, gy, gz)
        ni2 = 2.0 * _dot3(nx, ny, nz, ix_, iy_, iz_)
        rx, ry, rz = ni2 * nx - ix_, ni2 * ny - iy_, ni2 * nz - iz_
        t = _min(0.9 * iz, 0.01)
        if not _dot3(gx, gy, gz, rx, ry, rz) < t:
            continue
        bad += 1
        d = _dot3(nx, ny, nz, gx, gy, gz)                    # X axis: n's part orthogonal to ng
        xx, xy, xz = nx - d * gx, ny - d * gy, nz - d * gz
        x_len = np.sqrt(_dot3(xx, xy, xz, xx, xy, xz))
        if x_len > 1e-12:
            s = _max(x_len, 1e-300)
            xx, xy, xz = xx / s, xy / s, xz / s
        else:
            xx, xy, xz = nx, ny, nz
        ix = _dot3(ix_, iy_, iz_, xx, xy, xz)
        a = ix * ix + iz * iz
        b = np.sqrt(_max(ix * ix * (a - t * t), 0.0))
        c = iz * t + a
        fac = 0.5 / a
        n1z2, n2z2 = fac * (b + c), fac * (c - b)
        valid1 = n1z2 > 1e-5 and n1z2 <= 1.0 + 1e-5
        valid2 = n2z2 > 1e-5 and n2z2 <= 1.0 + 1e-5
        n1x, n1z = np.sqrt(_max(1.0 - n1z2, 0.0)), np.sqrt(_max(n1z2, 0.0))
        n2x, n2z = np.sqrt(_max(1.0 - n2z2, 0.0)), np.sqrt(_max(n2z2, 0.0))
        r1 = 2.0 * (n1x * ix + n1z * iz) * n1z - iz
        r2 = 2.0 * (n2x * ix + n2z * iz) * n2z - iz
        if valid1 and valid2:                                # the valid one; the shallower if both are
            pick1 = r1 < r2 if (r1 >= 1e-5 and r2 >= 1e-5) else r1 > r2
        else:
            pick1 = valid1
        px, pz = (n1x, n1z) if pick1 else (n2x, n2z)
        wx, wy, wz = px * xx + pz * gx, px * xy + pz * gy, px * xz + pz * gz
        if not (valid1 or valid2) or not (np.isfinite(wx) and np.isfinite(wy) and np.isfinite(wz)):
            wx, wy, wz = gx, gy, gz
        s = _max(np.sqrt(_dot3(wx, wy, wz, wx, wy, wz)), 1e-300)
        out[0, h], out[1, h], out[2, h] = wx / s, wy / s, wz / s
    return bad


def ensure_valid_reflection(ng, i, n):
    """shading_normals.ensure_valid_reflection (rows (3, N) each): n itself when no hit needs raising,
    else a new array."""
    c = np.ascontiguousarray
    out = np.empty((3, n.shape[1]))
    return out if _valid_reflection(c(ng, np.float64), c(i, np.float64), c(n, np.float64), out) else n


# -- the shadow terminator's lift ----------------------------------------------------------------------
@jit
def _terminator_lift(kind, prim, u, v, facing, start, stop, index, cutoffs, corners, triangles):
    m = stop - start
    lift = np.zeros((3, m))
    cutoff = np.zeros(m)
    anything = False
    vx, vy, vz = np.empty(3), np.empty(3), np.empty(3)
    nx_, ny_, nz_ = np.empty(3), np.empty(3), np.empty(3)
    for j in range(m):
        h = start + j
        if kind[h] != TRIANGLE:
            continue
        t = prim[h]
        r = index[t]
        if r < 0:
            continue
        cut = cutoffs[r]
        if not cut > 0.0:
            continue
        for c in range(3):
            vx[c], vy[c], vz[c] = triangles[t, c, 0], triangles[t, c, 1], triangles[t, c, 2]
            nx_[c], ny_[c], nz_[c] = corners[r, c, 0], corners[r, c, 1], corners[r, c, 2]
        w1, w2 = u[h], v[h]
        w0 = 1.0 - w1 - w2
        px = vx[0] * w0 + vx[1] * w1 + vx[2] * w2
        py = vy[0] * w0 + vy[1] * w1 + vy[2] * w2
        pz = vz[0] * w0 + vz[1] * w1 + vz[2] * w2
        nx = nx_[0] * w0 + nx_[1] * w1 + nx_[2] * w2
        ny = ny_[0] * w0 + ny_[1] * w1 + ny_[2] * w2
        nz = nz_[0] * w0 + nz_[1] * w1 + nz_[2] * w2
        a = _dot3(nx_[2] - nx_[0], ny_[2] - ny_[0], nz_[2] - nz_[0], vx[0] - vx[2], vy[0] - vy[2], vz[0] - vz[2])
        b = _dot3(nx_[2] - nx_[1], ny_[2] - ny_[1], nz_[2] - nz_[1], vx[1] - vx[2], vy[1] - vy[2], vz[1] - vz[2])
        cc = _dot3(nx_[1] - nx_[0], ny_[1] - ny_[0], nz_[1] - nz_[0], vx[1] - vx[0], vy[1] - vy[0], vz[1] - vz[0])
        hp = a * w0 * (w0 - 1.0) + (a + b + cc) * w0 * w1 + b * w1 * (w1 - 1.0)
        front = _dot3(nx, ny, nz, facing[0, h], facing[1, h], facing[2, h]) > 0.0
        above, below = 0.0, 0.0
        for i in range(3):
            to_p = _dot3(vx[i] - px, vy[i] - py, vz[i] - pz, nx_[i], ny_[i], nz_[i])
            edge_up, edge_down = 0.0, 0.0
            for k in range(3):
                if k == i:
                    continue
                d = _dot3(vx[k] - vx[i], vy[k] - vy[i], vz[k] - vz[i], nx_[i], ny_[i], nz_[i])
                edge_up = _max(edge_up, d)
                edge_down = _max(edge_down, -d)
            g_up = _max(to_p + edge_up, 0.0)
            g_down = _max(-to_p + edge_down, 0.0)
            if i == 0:
                above, below = g_up, g_down
            else:
                above, below = _min(above, g_up), _min(below, g_down)
        s = _max(above, hp * 0.5) if front else _min(-below, hp * 0.5)
        lift[0, j], lift[1, j], lift[2, j] = nx * s, ny * s, nz * s
        cutoff[j] = cut
        anything = True
    return lift, cutoff, anything


def terminator_lift(kind, prim, u, v, facing, span, index, cutoffs, corners, triangles):
    """SceneGeometry.terminator_lift's (lift rows (3, M), cutoff (M,)) of the hits in `span` of a batch
    (kind, prim, u, v: the batch's hit arrays; facing: its geometric normals towards the rays, rows), or
    None when no hit of the span gets a lift."""
    c = np.ascontiguousarray
    lift, cutoff, anything = _terminator_lift(c(kind, np.int8), c(prim, np.int64), c(u, np.float64),
                                              c(v, np.float64), c(facing, np.float64), span.start, span.stop,
                                              index, cutoffs, corners, triangles)
    return (lift, cutoff) if anything else None


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    n = 3
    prim, uv = np.zeros(n, np.int64), np.full(n, 0.25)
    corners = np.tile(np.eye(3), (1, 1, 1)).reshape(1, 3, 3)
    rows = np.tile(np.array([[0.0], [0.0], [1.0]]), (1, n))
    shading(prim, uv, uv, rows, np.zeros(1, np.int64), corners)
    ensure_valid_reflection(rows, rows, rows)
    triangles = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    terminator_lift(np.ones(n, np.int8), prim, uv, uv, rows, slice(0, n), np.zeros(1, np.int64), np.full(1, 0.1),
                    corners, triangles)
