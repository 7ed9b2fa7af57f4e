"""engine/materials/textures.py's image lookup (`lookup`: Closest and Linear, the four extension
modes) compiled with numba: one loop over the points that reads the texels it needs, instead of
NumPy's floor, casts, wraps and four fancy-index gathers of whole arrays.  Imported only through
engine/core/backend.py's choice (it imports numba); TextureSet (engine/materials/textures.py) calls
it for the "numba" backend.

The same float64 operations in the same order as `lookup` (u W - 0.5, floor, the fractions, the
bilinear blend ((1 - ty)((1 - tx) p00 + tx p10) + ty((1 - tx) p01 + tx p11)), texels cast to
float64 as they are stored (float32, or uint8 bytes as 0..255)), and the same integer texel
indices: a floor outside int64's range or NaN becomes int64's least value, as NumPy's cast does on
x86 (cvttsd2si), so the values are NumPy's bit for bit (tests/materials/test_textures_jit.py)."""
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


def warm_up() -> None:
    """Compile (or load) both kernels for the pixels a render passes (float32 as TextureSet keeps
    them, uint8 bytes) on valid inputs."""
    u = np.array([0.25, 1.5])
    for dtype in (np.float32, np.uint8):
        pixels = np.ones((2, 2, 4), dtype=dtype)
        for interpolation in ("Closest", "Linear"):
            lookup(pixels, u, u, interpolation, "REPEAT")
            lookup(pixels, u, u, interpolation, "CLIP", (3, 1))
