"""engine/scene/camera_rays.py's primary rays compiled with numba: each camera sample's raster
position (its pixel's corner plus the jitter), the point on the image plane, the direction through
it in world space and its normalisation, in one loop instead of some twenty array passes.  The same
float64 operations in the same order (camera_rays: the plane point, then x a0 + y a1 - a2 per
component, then the division by the square root of the sum of squares), so the same rays bit for
bit (tests/scene/test_camera_rays_jit.py).  Imported only through engine/core/backend.py's choice."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from .camera_rays import view_plane

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _rays(pixel, jx, jy, tile_width, x0, y0, width, height, plane_w, plane_h, shift_x, shift_y, axes, position):
    n = pixel.shape[0]
    origins = np.empty((3, n))
    directions = np.empty((3, n))
    for k in range(n):
        sx = np.float64((pixel[k] % tile_width) + x0) + jx[k]
        sy = np.float64((pixel[k] // tile_width) + y0) + jy[k]
        x = (sx / width - 0.5) * plane_w + shift_x
        y = (0.5 - sy / height) * plane_h + shift_y
        d0 = x * axes[0, 0] + y * axes[0, 1] - axes[0, 2]
        d1 = x * axes[1, 0] + y * axes[1, 1] - axes[1, 2]
        d2 = x * axes[2, 0] + y * axes[2, 1] - axes[2, 2]
        norm = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        directions[0, k], directions[1, k], directions[2, k] = d0 / norm, d1 / norm, d2 / norm
        origins[0, k], origins[1, k], origins[2, k] = position[0], position[1], position[2]
    return origins, directions


def tile_rays(camera, width: int, height: int, tile_width: int, x0: int, y0: int, pixel, jx, jy):
    """(origins, directions) rows of the camera samples of tile pixels `pixel` (the tile's x0, y0 and
    width) with jitters jx, jy: camera_rays at (pixel % tile_width + x0 + jx, pixel // tile_width + y0 + jy)."""
    plane_w, plane_h, extent = view_plane(camera, width, height)
    m = np.asarray(camera.matrix, dtype=np.float64)
    axes = np.ascontiguousarray(m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0))   # camera_rays' (object scale dropped)
    return _rays(np.ascontiguousarray(pixel, np.int64), np.ascontiguousarray(jx, np.float64),
                 np.ascontiguousarray(jy, np.float64), int(tile_width), int(x0), int(y0), float(width), float(height),
                 float(plane_w), float(plane_h), float(camera.shift_x * extent), float(camera.shift_y * extent), axes,
                 np.ascontiguousarray(m[:3, 3]))


class _Camera:
    sensor_fit, sensor_width, sensor_height, lens, shift_x, shift_y = "AUTO", 36.0, 24.0, 50.0, 0.0, 0.0
    matrix = np.eye(4)


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes."""
    tile_rays(_Camera(), 4, 4, 2, 0, 0, np.arange(4), np.full(4, 0.5), np.full(4, 0.5))
