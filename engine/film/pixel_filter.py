"""The pixel filter: where in and around its pixel each camera sample is taken, as Cycles does it.

Cycles importance-samples the pixel filter and weights every sample equally (scene/film.cpp
filter_table, kernel/camera/camera.h camera_sample): a table of 1024 raster offsets from the
pixel's corner, the inverse of the filter's CDF, is read at the sample's two filter numbers, one
per axis, so a sample's position follows the separable filter f(x) f(y) and the film adds it fully
to the pixel it was made for (engine/film/accumulator.py is unchanged).  The filters, over a
footprint W around the pixel centre (v from -W/2 to W/2):

  box              f = 1,                                           W = width
  gaussian         f = exp(-2 (6 v / W)^2) (sigma = width / 4),      W = 3 width
  blackman-harris  f = 0.35875 - 0.48829 cos(t) + 0.14128 cos(2t) - 0.01168 cos(3t),
                   t = 2 pi (v / W + 1/2),                          W = 2 width

The table is built as Cycles builds it (util/math_cdf: the CDF of the filter's half on 1023
points, inverted symmetrically on 1023 entries).  Cycles reads its table over 1024 entries whose
last one is never written (0): 1/1023 of its samples per axis land between the footprint's far
edge and the pixel's corner.  Here the 1023 written entries are read over [0, 1] instead, and the
box is exact: offset = u width + (1 - width) / 2, so a box of width 1 is the plain jitter u, the
same numbers bit for bit as before the filter existed.
"""
from __future__ import annotations

import numpy as np

from ..core.errors import SceneError

TABLE_SIZE = 1024                 # Cycles' FILTER_TABLE_SIZE
FOOTPRINT = {"box": 1.0, "gaussian": 3.0, "blackman-harris": 2.0}   # W / width (Cycles' filter_table)


def filter_function(kind: str, width: float):
    """f(v) of the filter over its footprint (v from the pixel centre, in pixels), unnormalised."""
    footprint = FOOTPRINT[kind] * width
    if kind == "box":
        return lambda v: np.ones_like(np.asarray(v, dtype=np.float64))
    if kind == "gaussian":
        return lambda v: np.exp(-2.0 * (np.asarray(v) * 6.0 / footprint) ** 2)
    def blackman_harris(v):
        t = 2.0 * np.pi * (np.asarray(v) / footprint + 0.5)
        return 0.35875 - 0.48829 * np.cos(t) + 0.14128 * np.cos(2.0 * t) - 0.01168 * np.cos(3.0 * t)
    return blackman_harris


def filter_table(kind: str, width: float) -> np.ndarray:
    """The 1023 raster offsets from the pixel's corner (0.5 = its centre) of Cycles' table."""
    half = 0.5 * FOOTPRINT[kind] * width                 # util_cdf_inverted(1024, 0, W / 2, f, symmetric)
    f = filter_function(kind, width)
    n = TABLE_SIZE - 1                                   # util_cdf_evaluate(1023, ...): 1024 CDF values
    x = half * np.arange(n) / (n - 1)
    cdf = np.concatenate([[0.0], np.cumsum(np.abs(f(x)))])
    cdf /= cdf[-1]
    cdf[-1] = 1.0
    half_size = (TABLE_SIZE - 1) // 2                    # util_cdf_invert, make_symmetric
    level = np.arange(half_size + 1) / half_size
    index = np.searchsorted(cdf, level, side="right")   # upper_bound
    inside = index < len(cdf) - 1
    i = np.minimum(index, len(cdf) - 2)
    t = np.where(inside, (level - cdf[i]) / (cdf[i + 1] - cdf[i]), 0.0)
    index = np.where(inside, index, len(cdf) - 1)
    y = (index + t) / (TABLE_SIZE - 1) * (2.0 * half)
    table = np.empty(2 * half_size + 1)
    table[half_size:] = 0.5 * (1.0 + y)
    table[half_size::-1] = 0.5 * (1.0 - y)
    return table


class PixelFilter:
    """offsets(u): raster offsets from the pixel corner for filter numbers u in [0, 1)."""

    def __init__(self, kind: str = "box", width: float = 1.0):
        if kind not in FOOTPRINT:
            raise SceneError(f"unknown pixel filter '{kind}' (expected one of {', '.join(FOOTPRINT)})")
        if not 0.0 < width:
            raise SceneError(f"pixel filter width must be above 0, got {width!r}")
        self.kind, self.width = kind, float(width)
        self.table = None if kind == "box" else filter_table(kind, width)

    @property
    def footprint(self) -> float:
        """The filter's extent in pixels (samples fall in [0.5 - W/2, 0.5 + W/2] of their pixel)."""
        return FOOTPRINT[self.kind] * self.width

    def offsets(self, u: np.ndarray) -> np.ndarray:
        if self.table is None:
            return u * self.width + (1.0 - self.width) * 0.5
        x = np.clip(u, 0.0, 1.0) * (len(self.table) - 1)
        return np.interp(x, np.arange(len(self.table)), self.table)


def pixel_filter_for(settings) -> PixelFilter | None:
    """The settings' filter, or None for a box of width 1 (the plain jitter: no work at all)."""
    if settings.pixel_filter == "box" and settings.filter_width == 1.0:
        return None
    return PixelFilter(settings.pixel_filter, settings.filter_width)
