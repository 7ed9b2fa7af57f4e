"""engine/materials/textures.py's image lookup (`lookup`: Closest and Linear, the four extension
modes) compiled with numba: one loop over the points that reads the texels it needs, instead of
NumPy's floor, casts, wraps and four fancy-index gathers of whole arrays.  Imported only through
engine/core/backend.py's choice (it imports numba); TextureSet (engine/materials/textures.py) calls
it for the "numba" backend.

The same float64 operations in the same order as `lookup` (u W - 0.5, floor, the fractions, the
bilinear blend ((1 - ty)((1 - tx) p00 + tx p10) + ty((1 - tx) p01 + tx p11)), texels cast to
float64 as they are stored (float32, or uint8 bytes as 0..255)), and the same integer texel
indices: a floor outside int64's range or NaN becomes int64's least value, as NumPy's cast does on
x86 (cvttsd2si), so the values are NumPy's bit for bit (tests/materials/test_textures_jit.py).

`light_points`: the first half of HitTextures.light_radiance (which light samples lie on a textured
emitter, the triangle of the emitter's pair each lies in and its barycentrics, and the corner UVs
interpolated there) in one loop over the samples, the same numbers as textures.py's `Barycentrics`
and `interpolate_uv` (tests/materials/test_light_points_jit.py)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

EXTENSIONS = {"REPEAT": 0, "EXTEND": 1, "CLIP": 2, "MIRROR": 3}
INT64_MIN = np.int64(-9223372036854775808)
LIMIT = 9.223372036854775808e18                   # 2^63: casts at or beyond it give INT64_MIN


@jit
def _int(f):
    """np.floor's float64 as int64, as NumPy's astype(np.int64) on x86 (NaN and out of range: INT64_MIN)."""
    if f >= -LIMIT and f < LIMIT:
        return np.int64(f)
    return INT64_MIN


@jit
def _wrap(i, n, extension):
    """textures._wrap for one index; CLIP: -1 outside."""
    if extension == 0:                                  # REPEAT (Python's floor modulo, as np.mod)
        return i % n
    if extension == 3:                                  # MIRROR
        period = i % (2 * n)
        return period if period < n else 2 * n - 1 - period
    if extension == 2:                                  # CLIP
        return i if i >= 0 and i < n else np.int64(-1)
    if i < 0:                                           # EXTEND
        return np.int64(0)
    return i if i < n - 1 else np.int64(n - 1)


@jit
def _closest(pixels, u, v, c0, extension, out):
    h, w = pixels.shape[0], pixels.shape[1]
    channels = out.shape[1]
    for k in range(u.shape[0]):
        ix = _wrap(_int(np.floor(u[k] * w)), w, extension)
        iy = _wrap(_int(np.floor(v[k] * h)), h, extension)
        if ix < 0 or iy < 0:
            for c in range(channels):
                out[k, c] = 0.0
        else:
            for c in range(channels):
                out[k, c] = np.float64(pixels[iy, ix, c0 + c])


@jit
def _linear(pixels, u, v, c0, extension, out):
    h, w = pixels.shape[0], pixels.shape[1]
    channels = out.shape[1]
    for k in range(u.shape[0]):
        x, y = u[k] * w - 0.5, v[k] * h - 0.5
        fx, fy = np.floor(x), np.floor(y)
        tx, ty = x - fx, y - fy
        ix, iy = _int(fx), _int(fy)
        x0, x1 = _wrap(ix, w, extension), _wrap(ix + 1, w, extension)
        y0, y1 = _wrap(iy, h, extension), _wrap(iy + 1, h, extension)
        for c in range(channels):
            cc = c0 + c
            p00 = 0.0 if x0 < 0 or y0 < 0 else np.float64(pixels[y0, x0, cc])
            p10 = 0.0 if x1 < 0 or y0 < 0 else np.float64(pixels[y0, x1, cc])
            p01 = 0.0 if x0 < 0 or y1 < 0 else np.float64(pixels[y1, x0, cc])
            p11 = 0.0 if x1 < 0 or y1 < 0 else np.float64(pixels[y1, x1, cc])
            out[k, c] = ((1 - ty) * ((1 - tx) * p00 + tx * p10)
                         + ty * ((1 - tx) * p01 + tx * p11))


def lookup(pixels, u, v, interpolation="Linear", extension="REPEAT", channels=None):
    """textures.lookup (N, C) of `pixels` (H, W, C) C-contiguous float32 or uint8, compiled; `channels`:
    (first, count) of the channels to read (default all), instead of a strided view of them."""
    first, count = (0, pixels.shape[2]) if channels is None else channels
    u = np.ascontiguousarray(u, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    out = np.empty((len(u), count))
    kernel = _closest if interpolation == "Closest" else _linear
    kernel(pixels, u, v, first, EXTENSIONS.get(extension, 1), out)
    return out


@jit
def _bary(k, px, py, pz, v0, e1, e2, d11, d12, d22):
    """textures.Barycentrics for one point in triangle k of the set: w = p - v0, its dot products with
    the edges summed as NumPy's sum over the rows ((0.0 + 0) + 1) + 2, then the Gram inverse."""
    w0, w1, w2 = px - v0[0, k], py - v0[1, k], pz - v0[2, k]
    s1 = ((0.0 + w0 * e1[0, k]) + w1 * e1[1, k]) + w2 * e1[2, k]
    s2 = ((0.0 + w0 * e2[0, k]) + w1 * e2[1, k]) + w2 * e2[2, k]
    c12 = d12[k]
    return d22[k] * s1 - c12 * s2, d11[k] * s2 - c12 * s1


@jit
def _light_points(light, point, light_a, light_b, emitting, triangle_material, v0, e1, e2, d11, d12, d22,
                  tri_uv, triangles, sel, tri, material, b1, b2, u, v, position):
    n_lights = light_a.shape[0]
    with_uv = u.shape[0] > 0
    with_position = position.shape[0] > 0
    count = 0
    for i in range(light.shape[0]):
        lamp = light[i]
        if lamp >= n_lights:
            continue
        a = light_a[lamp]
        if a < 0:
            continue
        px, py, pz = point[0, i], point[1, i], point[2, i]
        c1, c2 = _bary(a, px, py, pz, v0, e1, e2, d11, d12, d22)
        k = a
        b = light_b[lamp]
        if b >= 0 and (c1 < 0 or c2 < 0 or c1 + c2 > 1):        # the pair's second triangle
            k = b
            c1, c2 = _bary(b, px, py, pz, v0, e1, e2, d11, d12, d22)
        t = emitting[k]
        sel[count], tri[count], material[count], b1[count], b2[count] = i, t, triangle_material[t], c1, c2
        if with_uv:                                     # interpolate_uv: b0 c0 + b1 c2 + b2 c4, ...
            c0 = (1.0 - c1) - c2
            u[count] = (c0 * tri_uv[0, t] + c1 * tri_uv[2, t]) + c2 * tri_uv[4, t]
            v[count] = (c0 * tri_uv[1, t] + c1 * tri_uv[3, t]) + c2 * tri_uv[5, t]
        if with_position:                               # engine/nodes/context.py bary: b0 v0 + b1 v1 + b2 v2
            c0 = (1.0 - c1) - c2
            for x in range(3):
                position[count, x] = (c0 * triangles[t, 0, x] + c1 * triangles[t, 1, x]) + c2 * triangles[t, 2, x]
        count += 1
    return count


def light_points(light, point, light_a, light_b, emitting, triangle_material, terms, tri_uv=None, triangles=None):
    """(sel, tri, material, b1, b2, u, v) of the light samples (`light` (N,) light numbers, `point`
    rows (3, N)) that lie on a textured emitter: HitTextures.light_radiance's selection (light_a,
    light_b: the first and last of each light's triangles, numbers into `emitting`, -1 for none),
    the emitter's triangle each lies in (of a pair: the second where the first one's barycentrics
    fall outside it), its material, the barycentrics (b1, b2) there from textures.Barycentrics'
    `terms` (v0, e1, e2, d11, d12, d22), and with
    `tri_uv` (rows (6, T)) interpolate_uv's (u, v) (else u and v are empty); with `triangles` (T, 3, 3)
    also the points' positions from the corners as engine/nodes/context.py's `bary` gives them (rows
    (3, k) of a (k, 3) array, its layout), else None."""
    n = len(light)
    sel, tri, material = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n, np.int64)
    b1, b2 = np.empty(n), np.empty(n)
    u, v = (np.empty(n), np.empty(n)) if tri_uv is not None else (np.empty(0), np.empty(0))
    position = np.empty((n if triangles is not None else 0, 3))
    count = _light_points(np.ascontiguousarray(light, dtype=np.int64), np.ascontiguousarray(point, dtype=np.float64),
                          light_a, light_b, emitting, triangle_material, *terms,
                          np.zeros((6, 1)) if tri_uv is None else tri_uv,
                          np.zeros((1, 3, 3)) if triangles is None else triangles,
                          sel, tri, material, b1, b2, u, v, position)
    if tri_uv is not None:
        u, v = u[:count], v[:count]
    rows = position[:count].T if triangles is not None else None
    return sel[:count], tri[:count], material[:count], b1[:count], b2[:count], u, v, rows


def warm_up() -> None:
    """Compile (or load) both kernels for the pixels a render passes (float32 as TextureSet keeps
    them, uint8 bytes) on valid inputs."""
    u = np.array([0.25, 1.5])
    for dtype in (np.float32, np.uint8):
        pixels = np.ones((2, 2, 4), dtype=dtype)
        for interpolation in ("Closest", "Linear"):
            lookup(pixels, u, u, interpolation, "REPEAT")
            lookup(pixels, u, u, interpolation, "CLIP", (3, 1))
    _warm_light_points()


def _warm_light_points():
    """light_points on a unit square's two triangles (one light), with and without UVs."""
    rows = np.ascontiguousarray(np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]))
    edges = np.ascontiguousarray(np.array([[1.0, 1.0], [0.0, 1.0], [0.0, 0.0]]))
    terms = (rows, edges, edges.copy(), np.ones(2), np.zeros(2), np.ones(2))
    point = np.array([[0.75, 0.25], [0.25, 0.75], [0.0, 0.0]])
    one = np.zeros(1, np.int64)
    corners = np.zeros((2, 3, 3))
    for tri_uv, triangles in ((None, None), (np.ascontiguousarray(np.ones((6, 2))), corners)):
        light_points(np.zeros(2, np.int64), point, one, np.ones(1, np.int64), np.arange(2, dtype=np.int64),
                     np.zeros(2, np.int64), terms, tri_uv, triangles)
