"""Primary rays of a Blender perspective camera, pixel centres as Cycles (+0.5)."""
from __future__ import annotations

import numpy as np

from ..core.vec import normalize


def view_plane(camera, width: int, height: int):
    """Size of the image plane at distance 1 and the extent that shift is measured in.

    Blender's sensor fit: AUTO applies sensor_width to the larger image side;
    HORIZONTAL fits sensor_width to the width, VERTICAL sensor_height to the height.
    Shift is a fraction of the fitted side.
    """
    fit = camera.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if width >= height else "VERTICAL"
        sensor = camera.sensor_width
    else:
        sensor = camera.sensor_width if fit == "HORIZONTAL" else camera.sensor_height
    extent = sensor / camera.lens
    if fit == "HORIZONTAL":
        plane_w, plane_h = extent, extent * height / width
    else:
        plane_w, plane_h = extent * width / height, extent
    return plane_w, plane_h, extent


def camera_rays(camera, width: int, height: int, sx: np.ndarray, sy: np.ndarray):
    """Rays through raster positions (sx, sy): x to the right, y down from the top edge.

    Returns (origins, unit directions) in world space, as rows (3, N) (engine/core/vec.py).
    """
    plane_w, plane_h, extent = view_plane(camera, width, height)
    x = (sx / width - 0.5) * plane_w + camera.shift_x * extent
    y = (0.5 - sy / height) * plane_h + camera.shift_y * extent
    m = np.asarray(camera.matrix, dtype=np.float64)
    axes = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)  # drop object scale
    # Per component, not a matmul: that wakes OpenBLAS's thread pool, whose spinning
    # threads steal the other core from a second render worker.
    directions = np.empty((3, len(x)))
    for i in range(3):
        directions[i] = x * axes[i, 0] + y * axes[i, 1] - axes[i, 2]
    directions = normalize(directions)
    origins = np.repeat(m[:3, 3:4], len(x), axis=1)
    return origins, directions


class TileSamples:
    """The camera samples of one image tile, handed out in chunks (report 2.3).

    Sample i of the tile belongs to pixel i mod (tile pixels): the first sweep gives every pixel
    its sample 0, the second its sample 1, ... up to sample `spp` - 1, from sample `first` on.
    Each sample is a jittered sub-pixel position from dimension pair 0 of `sampler`
    (engine/sampling/qmc.py) when its chunk is taken: inside the pixel (a box of width 1), or
    moved by `pixel_filter` (engine/film/pixel_filter.py PixelFilter.offsets, None: the box).
    """

    compiled = None     # engine/scene/camera_rays_jit.py where the backend is numba (engine/rendering/session.py)

    def __init__(self, camera, width: int, height: int, x0: int, y0: int, x1: int, y1: int,
                 spp: int, sampler, first: int = 0, pixel_filter=None):
        """Samples first .. spp-1 of every pixel (a work unit's sample range)."""
        self.camera, self.width, self.height = camera, width, height
        self.tile_width = x1 - x0
        self.pixels = self.tile_width * (y1 - y0)
        self.x0, self.y0 = x0, y0
        self.total = self.pixels * spp
        self.taken = self.pixels * first
        self.sampler = sampler
        self.pixel_filter = pixel_filter

    @property
    def remaining(self) -> int:
        return self.total - self.taken

    def take(self, count: int):
        """(pixel index within the tile, sample index within the pixel, origins, directions)
        of the next `count` samples."""
        count = min(count, self.remaining)
        serial = np.arange(self.taken, self.taken + count)
        pixel, sample = serial % self.pixels, serial // self.pixels
        self.taken += count
        return self.rays(pixel, sample)

    def rays(self, pixel, sample):
        """(pixel, sample, origins, directions): the jittered camera rays of these tile pixels'
        samples (jitter from dimension pair 0 of the sampler, through the pixel filter)."""
        jx, jy = self.sampler.pair(pixel, sample, 0)
        if self.compiled is not None:           # the same rays in one loop, the filter's table read there
            origins, directions = self.compiled.tile_rays(self.camera, self.width, self.height, self.tile_width,
                                                          self.x0, self.y0, pixel, jx, jy, self.pixel_filter)
            return pixel, sample.astype(np.int64), origins, directions
        if self.pixel_filter is not None:
            jx, jy = self.pixel_filter.offsets(jx), self.pixel_filter.offsets(jy)
        sx = (pixel % self.tile_width + self.x0) + jx
        sy = (pixel // self.tile_width + self.y0) + jy
        origins, directions = camera_rays(self.camera, self.width, self.height, sx, sy)
        return pixel, sample.astype(np.int64), origins, directions
