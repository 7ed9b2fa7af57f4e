"""Camera samples of some pixels of a tile only: what adaptive sampling hands the tracer.

The same interface and sample numbering as engine/scene/camera_rays.py TileSamples (sample by
sample over the pixels, jitter from dimension pair 0 of the sampler, which is keyed by the tile
pixel and the sample number), so an active pixel's samples are exactly those it would get in a full tile: adaptive
sampling changes how many samples a pixel gets, never which ones.
"""
from __future__ import annotations

import numpy as np

from ..scene.camera_rays import TileSamples


def pack_mask(active: np.ndarray) -> bytes:
    """A tile's (h, w) bool mask of active pixels as bytes (hashable, small to send)."""
    return np.packbits(np.asarray(active, dtype=bool).ravel()).tobytes()


def unpack_mask(mask: bytes, pixels: int) -> np.ndarray:
    return np.unpackbits(np.frombuffer(mask, dtype=np.uint8), count=pixels).astype(bool)


class MaskedTileSamples:
    """Samples first .. spp-1 of the active pixels (indices within the tile) of one tile."""

    def __init__(self, camera, width: int, height: int, x0: int, y0: int, x1: int, y1: int,
                 spp: int, sampler, active: np.ndarray, first: int = 0, pixel_filter=None):
        self.camera, self.width, self.height = camera, width, height
        self.tile_width = x1 - x0
        self.x0, self.y0 = x0, y0
        self.active = np.flatnonzero(active) if active.dtype == bool else np.asarray(active)
        n = len(self.active)
        self.total = n * (spp - first)
        self.taken = 0
        self.first = first
        self.sampler = sampler
        self.pixel_filter = pixel_filter

    @property
    def remaining(self) -> int:
        return self.total - self.taken

    def take(self, count: int):
        count = min(count, self.remaining)
        serial = np.arange(self.taken, self.taken + count)
        n = len(self.active)
        pixel = self.active[serial % n]
        sample = serial // n + self.first
        self.taken += count
        return self.rays(pixel, sample)

    rays = TileSamples.rays
    compiled = None     # as TileSamples
