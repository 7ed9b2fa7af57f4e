"""engine/nodes/normals.py's bump shadowing term (Blender 4.x / 5.0) compiled with numba: PathTracer.bump_shadowing's
smooth normal towards the ray (repeated per shadow ray) and bump_shadowing / _bump_term_4x per direction in
one loop instead of some thirty NumPy passes; and the Normal Map node in tangent space (`tangent_normal_map`:
tangent_space_normal, the strength's blend and the fallbacks of normal_map) in one loop instead of some
forty; at a scene's hits (`corner_normal_map`) the same loop also interpolates the context's tangent and
bitangent sign from the triangles' corners (engine/nodes/context.py tangent, tangent_sign, has_tangent,
tangent_base): no (3, N) temporaries.  Imported only through engine/core/backend.py's choice (it imports
numba; kernel name "wavefront").

Inputs are (3, N) rows and (N,) values of one length: bump_shadowing refuses others (ValueError, not a
read past an array's end); the Normal Map's colour and strength may be given as one (broadcast: a copy).

The float operations are the NumPy code's, in its order and precision (normals.py's _dot, a sum over the
three rows, is (x + y) + z as engine/core/vec.py dot; x ** 2 is x * x; np.clip, np.maximum with their NaN
rule): the same numbers bit for bit (tests/geometry/test_shading_normals_jit.py)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from ..geometry.shading_normals_jit import _dot3, _max, _min
from ..core.kernel_inputs import contiguous, fitted   # inputs as contiguous read-only arrays: one signature

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

NO_ROWS = np.zeros((3, 1))
NO_CORNERS, NO_SIGNS = contiguous(np.zeros((0, 3, 3))), contiguous(np.zeros((0, 3)))   # a scene without tangents


@jit
def _term_4x(sx, sy, sz, nx, ny, nz, wx, wy, wz, diffuse, is_eval):
    cos_si = _dot3(sx, sy, sz, wx, wy, wz)
    cos_sn = _dot3(sx, sy, sz, nx, ny, nz)
    cos_ni = _dot3(nx, ny, nz, wx, wy, wz)
    if cos_si * cos_sn * cos_ni < 0.0 and (is_eval or diffuse):
        return 0.0
    if not diffuse:
        return 1.0
    cos_i, cos_d = abs(cos_si), abs(cos_sn)
    if cos_d >= 1.0 or cos_i >= 1.0:
        return 1.0
    if cos_i < 1e-6:
        return 0.0
    md = _max(cos_d, 1e-300)
    tan2_d = 1.0 / (md * md) - 1.0
    alpha2 = _min(_max(0.125 * tan2_d, 0.0), 1.0)
    mi = _max(cos_i, 1e-300)
    c2 = mi * mi
    lam = 0.5 * (np.sqrt(1.0 + alpha2 * (1.0 - c2) / c2) - 1.0)
    return 1.0 / (1.0 + lam)


@jit
def _bump_shadowing(direction, normal, shading, has_shading, n, wi, diffuse, is_eval, repeat):
    k = wi.shape[1]
    out = np.empty(k)
    for c in range(k):
        i = c // repeat
        gx, gy, gz = normal[0, i], normal[1, i], normal[2, i]
        towards = 1.0 if _dot3(direction[0, i], direction[1, i], direction[2, i], gx, gy, gz) < 0.0 else -1.0
        if has_shading:
            gx, gy, gz = shading[0, i], shading[1, i], shading[2, i]
        sx, sy, sz = gx * towards, gy * towards, gz * towards
        nx, ny, nz = n[0, i], n[1, i], n[2, i]
        if sx == nx and sy == ny and sz == nz:
            out[c] = 1.0
        else:
            out[c] = _term_4x(sx, sy, sz, nx, ny, nz, wi[0, c], wi[1, c], wi[2, c], diffuse[c], is_eval)
    return out


def bump_shadowing(direction, normal, shading, n, wi, diffuse, is_eval, repeat=1):
    """PathTracer.bump_shadowing under Blender 4.x / 5.0: (K,) for the directions wi (3, K), K = M x
    repeat, at M hits with ray directions `direction`, geometric normals `normal`, smooth normals
    `shading` (None: flat) and the BSDF's normal n (rows (3, M)); diffuse (K,) bool or one bool."""
    k = wi.shape[1]
    rows = (3, k // repeat) if repeat >= 1 else None
    if (rows is None or rows[1] * repeat != k or direction.shape != rows or normal.shape != rows or n.shape != rows
            or (shading is not None and shading.shape != rows)):
        raise ValueError(f"bump_shadowing: {k} directions, repeat {repeat}: the hits' rows must be {rows}, not direction "
                         f"{direction.shape}, normal {normal.shape}, shading {getattr(shading, 'shape', None)}, n {n.shape}")
    diffuse = np.ascontiguousarray(np.broadcast_to(np.asarray(diffuse, dtype=np.bool_), (k,)))
    has = shading is not None
    c = np.ascontiguousarray
    return _bump_shadowing(c(direction, np.float64), c(normal, np.float64),
                           c(shading, np.float64) if has else NO_ROWS, has, c(n, np.float64), c(wi, np.float64),
                           diffuse, bool(is_eval), int(repeat))


@jit
def _safe_normalize(x, y, z):
    """normals.safe_normalize of one vector: v / |v|, 0 where |v| is not > 0."""
    length = np.sqrt(_dot3(x, y, z, x, y, z))
    if length > 0.0:
        return x / length, y / length, z / length
    return 0.0, 0.0, 0.0


@jit
def _mapped(c0, c1, c2, st, tx, ty, tz, sg, bx, by, bz, back, has, sx, sy, sz, new, linear):
    """One hit's Normal Map in tangent space (normals.normal_map's numbers): the colour's components
    c, strength st, tangent t, bitangent sign sg, base normal b, backfacing, has_tangent, the shading
    normal s."""
    c0, c1, c2 = 2.0 * (c0 - 0.5), 2.0 * (c1 - 0.5), 2.0 * (c2 - 0.5)
    if new:                                       # Blender 4.x / 5.0: the strength in tangent space
        c0, c1, c2 = c0 * st, c1 * st, 1.0 + (c2 - 1.0) * _min(_max(st, 0.0), 1.0)
    ux, uy, uz = sg * (by * tz - bz * ty), sg * (bz * tx - bx * tz), sg * (bx * ty - by * tx)   # bitangent
    nx, ny, nz = _safe_normalize(c0 * tx + c1 * ux + c2 * bx, c0 * ty + c1 * uy + c2 * by,
                                 c0 * tz + c1 * uz + c2 * bz)
    if back:
        nx, ny, nz = -nx, -ny, -nz
    if not has:                                   # no tangents: N
        nx, ny, nz = sx, sy, sz
    if linear and st != 1.0:                      # Blender 3.x: a linear blend with N
        s = _max(st, 0.0)
        nx, ny, nz = _safe_normalize(sx + (nx - sx) * s, sy + (ny - sy) * s, sz + (nz - sz) * s)
    finite = np.isfinite(nx) and np.isfinite(ny) and np.isfinite(nz)
    if not finite or not (abs(nx) > 0 or abs(ny) > 0 or abs(nz) > 0):
        return sx, sy, sz
    return nx, ny, nz


@jit
def _tangent_normal_map(color, strength, tangent, sign, base, backfacing, has, shading, new, linear, out):
    for h in range(color.shape[1]):
        out[0, h], out[1, h], out[2, h] = _mapped(
            color[0, h], color[1, h], color[2, h], strength[h], tangent[0, h], tangent[1, h], tangent[2, h],
            sign[h], base[0, h], base[1, h], base[2, h], backfacing[h], has[h],
            shading[0, h], shading[1, h], shading[2, h], new, linear)


def tangent_normal_map(color, strength, tangent, sign, base, backfacing, has, shading, cycles_version):
    """normals.normal_map's "Normal" in tangent space: colour rows (3, N), strength (N,), the context's
    tangent, tangent_sign, tangent_base, backfacing (N,) bool, has_tangent and normal (each broadcast
    to N hits when given as one: a copy)."""
    m = shading.shape[1]
    rows, values = (3, m), (m,)
    out = np.empty(rows)
    new = tuple(cycles_version) >= (4, 0)
    color = np.asarray(color, np.float64).reshape(3, -1)              # a constant colour: (3,)
    _tangent_normal_map(fitted(color, rows), fitted(strength, values), fitted(tangent, rows), fitted(sign, values),
                        fitted(base, rows), fitted(backfacing, values, np.bool_), fitted(has, values, np.bool_),
                        fitted(shading, rows), new, not new, out)
    return out


@jit
def _corner_normal_map(color, strength, kind, prim, b1, b2, triangle, has_corners, tangents, signs, shading,
                       towards, new, linear, out):
    for h in range(shading.shape[1]):
        tx = ty = tz = sg = 0.0                   # off triangles (or without tangents): none
        if has_corners and kind[h] == triangle:   # context.py's bary and tangent_sign, per hit
            p, u, v = prim[h], b1[h], b2[h]
            if p < 0 or p >= tangents.shape[0]:   # as NumPy's take refuses it, not a read past the end
                raise IndexError("normals_jit.corner_normal_map: a triangle hit's primitive outside the tangents")
            w = 1.0 - u - v
            tx = w * tangents[p, 0, 0] + u * tangents[p, 1, 0] + v * tangents[p, 2, 0]
            ty = w * tangents[p, 0, 1] + u * tangents[p, 1, 1] + v * tangents[p, 2, 1]
            tz = w * tangents[p, 0, 2] + u * tangents[p, 1, 2] + v * tangents[p, 2, 2]
            sg = w * signs[p, 0] + u * signs[p, 1] + v * signs[p, 2]
        has = sg != 0.0 and tx * tx + ty * ty + tz * tz > 0.0      # squares >= 0: > 0 in any order
        t = towards[h]
        sx, sy, sz = shading[0, h], shading[1, h], shading[2, h]
        out[0, h], out[1, h], out[2, h] = _mapped(
            color[0, h], color[1, h], color[2, h], strength[h], tx, ty, tz, sg, sx * t, sy * t, sz * t,
            t < 0.0, has, sx, sy, sz, new, linear)


def corner_normal_map(color, strength, corners, shading, towards, cycles_version):
    """tangent_normal_map at a scene's hits, the context's tangent attributes made per hit in the same
    loop (engine/nodes/context.py TangentCorners: the hits' kind, prim, b1, b2 and the triangles' corner
    tangents and signs), with the context's `normal` (3, N) and `_towards` (N,) (tangent_base is
    normal x towards, backfacing towards < 0): no (3, N) tangent, base or sign arrays."""
    m = shading.shape[1]
    rows, values = (3, m), (m,)
    if towards.shape != values or any(len(a) != m for a in (corners.kind, corners.prim, corners.b1, corners.b2)):
        raise ValueError(f"corner_normal_map: {m} hits but towards {towards.shape}, kind / prim / b1 / b2 of "
                         f"{[len(a) for a in (corners.kind, corners.prim, corners.b1, corners.b2)]}")
    out = np.empty(rows)
    new = tuple(cycles_version) >= (4, 0)
    color = np.asarray(color, np.float64).reshape(3, -1)              # a constant colour: (3,)
    has = corners.tangents is not None and corners.signs is not None
    _corner_normal_map(fitted(color, rows), fitted(strength, values), contiguous(corners.kind, np.int8),
                       contiguous(corners.prim, np.int64), contiguous(corners.b1), contiguous(corners.b2),
                       corners.triangle_kind, has,
                       contiguous(corners.tangents) if has else NO_CORNERS,
                       contiguous(corners.signs) if has else NO_SIGNS,
                       fitted(shading, rows), contiguous(towards), new, not new, out)
    return out


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    ones, yes = np.ones(3), np.ones(3, np.bool_)
    rows = np.tile(np.array([[0.0], [0.6], [0.8]]), (1, 3))
    for shade in (rows, None):
        bump_shadowing(-rows, rows, shade, rows[::-1].copy(), rows, np.ones(3, bool), True, 1)
    tangent_normal_map(rows, ones, rows, ones, rows, yes, yes, rows, (5, 0))
    from .context import TangentCorners
    kind, prim = np.ones(3, np.int8), np.zeros(3, np.int64)
    for tangents, signs in ((np.ones((1, 3, 3)), np.ones((1, 3))), (None, None)):
        corner_normal_map(rows, ones, TangentCorners(kind, prim, ones / 3, ones / 3, 1, tangents, signs), rows, ones,
                          (5, 0))
