"""engine/scene/camera_rays.py's primary rays compiled with numba: each camera sample's raster
position (its pixel's corner plus the jitter), the point on the image plane, the direction through
it in world space and its normalisation, in one loop instead of some twenty array passes.  The same
float64 operations in the same order (camera_rays: the plane point, then x a0 + y a1 - a2 per
component, then the division by the square root of the sum of squares), so the same rays bit for
bit (tests/scene/test_camera_rays_jit.py).  A pixel filter with a table (engine/film/pixel_filter.py
PixelFilter.offsets) is read here too, as np.interp reads it (tests/scene/test_camera_rays_jit.py).  Imported only through engine/core/backend.py's choice."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from .camera_rays import view_plane

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def filter_offset(u, table):
    """PixelFilter.offsets(u) of a filter with a table: np.interp(clip(u, 0, 1) (len - 1), 0 .. len - 1,
    table) with numpy's operations (numpy/core/src/multiarray/compiled_base.c arr_interp): at a
    knot x == j its value, else (table[j + 1] - table[j]) / 1 (x - j) + table[j] for j <= x < j + 1,
    and the last value at and above the last knot."""
    last = table.shape[0] - 1
    x = min(max(u, 0.0), 1.0) * np.float64(last)
    if not x < last:                       # x == last (or NaN: np.interp gives the last value too)
        return table[last]
    j = int(x)
    if x == j:
        return table[j]
    return (table[j + 1] - table[j]) * (x - j) + table[j]


@jit
def filter_offsets(u, table):
    """filter_offset over an array (tests/scene/test_camera_rays_jit.py)."""
    out = np.empty(u.shape[0])
    for k in range(u.shape[0]):
        out[k] = filter_offset(u[k], table)
    return out


@jit
def _rays(pixel, jx, jy, table, tile_width, x0, y0, width, height, plane_w, plane_h, shift_x, shift_y, axes,
          position):
    n = pixel.shape[0]
    origins = np.empty((3, n))
    directions = np.empty((3, n))
    filtered = table.shape[0] > 0
    for k in range(n):
        ox, oy = jx[k], jy[k]
        if filtered:
            ox, oy = filter_offset(ox, table), filter_offset(oy, table)
        sx = np.float64((pixel[k] % tile_width) + x0) + ox
        sy = np.float64((pixel[k] // tile_width) + y0) + oy
        x = (sx / width - 0.5) * plane_w + shift_x
        y = (0.5 - sy / height) * plane_h + shift_y
        d0 = x * axes[0, 0] + y * axes[0, 1] - axes[0, 2]
        d1 = x * axes[1, 0] + y * axes[1, 1] - axes[1, 2]
        d2 = x * axes[2, 0] + y * axes[2, 1] - axes[2, 2]
        norm = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        directions[0, k], directions[1, k], directions[2, k] = d0 / norm, d1 / norm, d2 / norm
        origins[0, k], origins[1, k], origins[2, k] = position[0], position[1], position[2]
    return origins, directions


_NO_TABLE = np.empty(0)


def tile_rays(camera, width: int, height: int, tile_width: int, x0: int, y0: int, pixel, jx, jy, pixel_filter=None):
    """(origins, directions) rows of the camera samples of tile pixels `pixel` (the tile's x0, y0 and
    width) with jitters jx, jy moved by `pixel_filter` (None: the box of width 1): camera_rays at
    (pixel % tile_width + x0 + ox, pixel // tile_width + y0 + oy), (ox, oy) = the filter's offsets."""
    table = _NO_TABLE
    if pixel_filter is not None:
        if pixel_filter.table is None:              # a box of another width: a multiply-add, left to NumPy
            jx, jy = pixel_filter.offsets(jx), pixel_filter.offsets(jy)
        else:
            table = np.ascontiguousarray(pixel_filter.table, np.float64)
    plane_w, plane_h, extent = view_plane(camera, width, height)
    m = np.asarray(camera.matrix, dtype=np.float64)
    axes = np.ascontiguousarray(m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0))   # camera_rays' (object scale dropped)
    return _rays(np.ascontiguousarray(pixel, np.int64), np.ascontiguousarray(jx, np.float64),
                 np.ascontiguousarray(jy, np.float64), table, int(tile_width), int(x0), int(y0), float(width), float(height),
                 float(plane_w), float(plane_h), float(camera.shift_x * extent), float(camera.shift_y * extent), axes,
                 np.ascontiguousarray(m[:3, 3]))


class _Camera:
    sensor_fit, sensor_width, sensor_height, lens, shift_x, shift_y = "AUTO", 36.0, 24.0, 50.0, 0.0, 0.0
    matrix = np.eye(4)


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes."""
    tile_rays(_Camera(), 4, 4, 2, 0, 0, np.arange(4), np.full(4, 0.5), np.full(4, 0.5))
