"""The film: per-pixel radiance sums, sums of squares and sample counts over a grid of pixels.

One accumulator for every grid the renderer keeps: a work unit's tile (samples go in), the frame
(tiles go in, engine/rendering/frame.py) and the viewport (whole frames go in,
engine/pools/viewport.py).  The pixel mean and the variance of the pixel mean are computed here
only.  Every sample counts fully in the pixel it was made for: the pixel filter is in where the
camera samples are taken (engine/film/pixel_filter.py), as Cycles.  With a transparent film it also
counts the camera samples that saw the background (`transparent`): alpha = 1 - transparent / count.
"""
from __future__ import annotations

import numpy as np

FLOAT32_MAX = float(np.finfo(np.float32).max)     # about 3.4e38: a variance beyond is written as this


class Film:
    """sum, sum_sq: (height, width, 3); count: (height, width) samples per pixel; transparent:
    (height, width) samples that saw the background, or None (an opaque film); exposure: Cycles'
    film exposure, the scale of what `display` shows."""
    exposure = 1.0

    def __init__(self, width: int, height: int, transparent: bool = False):
        self.width, self.height = width, height
        self.sum = np.zeros((height, width, 3))
        self.sum_sq = np.zeros((height, width, 3))
        self.count = np.zeros((height, width))
        self.transparent = np.zeros((height, width)) if transparent else None

    def add_samples(self, pixel: np.ndarray, radiance: np.ndarray) -> None:
        """Samples' radiance as rows (3, N) (engine/core/vec.py) into their pixels (flat indices)."""
        n = self.width * self.height
        count, total, squares = self.count.reshape(n), self.sum.reshape(n, 3), self.sum_sq.reshape(n, 3)
        count += np.bincount(pixel, minlength=n)
        for c in range(3):
            total[:, c] += np.bincount(pixel, weights=radiance[c], minlength=n)
            squares[:, c] += np.bincount(pixel, weights=radiance[c] * radiance[c], minlength=n)

    def add_every_pixel(self, radiance: np.ndarray) -> None:
        """add_samples of S samples of every pixel in sample-major order (column s n + p: pixel p's sample s,
        n = width x height), with the same sums bit for bit: NumPy's reduction over the samples' axis of
        the (S, n) rows adds them one after the other in sample order, as bincount does (a third of its
        time).  One pixel: bincount (the reduction of a single column would sum pairwise)."""
        n = self.width * self.height
        if n < 2:
            self.add_samples(np.tile(np.arange(n), radiance.shape[1] // max(n, 1)), radiance)
            return
        rows = radiance.reshape(3, -1, n)
        self.count.reshape(n)[:] += rows.shape[1]
        self.sum.reshape(n, 3)[:] += np.add.reduce(rows, axis=1).T
        self.sum_sq.reshape(n, 3)[:] += np.add.reduce(rows * rows, axis=1).T

    def add_transparent(self, pixel: np.ndarray, weight: np.ndarray) -> None:
        """Camera samples (their pixels' flat indices) that left the scene, each with its weight:
        Cycles' transparent background counts the mean throughput, 1 for a camera ray."""
        self.transparent.reshape(-1)[:] += np.bincount(pixel, weights=weight, minlength=self.width * self.height)

    def add_sums(self, x0: int, y0: int, total: np.ndarray, squares: np.ndarray, count, transparent=None) -> None:
        """Another film's sums (h, w, 3) into the pixels from (x0, y0); `count` (h, w) or a number;
        `transparent` (h, w) when both films are transparent."""
        h, w = total.shape[:2]
        self.sum[y0:y0 + h, x0:x0 + w] += total
        self.sum_sq[y0:y0 + h, x0:x0 + w] += squares
        self.count[y0:y0 + h, x0:x0 + w] += count
        if transparent is not None and self.transparent is not None:
            self.transparent[y0:y0 + h, x0:x0 + w] += transparent

    @staticmethod
    def _region(tile):
        return (slice(None), slice(None)) if tile is None else (slice(tile.y0, tile.y1), slice(tile.x0, tile.x1))

    def mean(self, tile=None) -> np.ndarray:
        """(h, w, 3) float32 pixel means of the whole film or of `tile` (x0, y0, x1, y1); 0 without samples."""
        s = self._region(tile)
        with np.errstate(invalid="ignore", divide="ignore"):
            m = self.sum[s] / self.count[s][..., None]
        return np.nan_to_num(m).astype(np.float32)

    def display(self, tile=None) -> np.ndarray:
        """(h, w, 3) float32 pixels of the film or of `tile` as shown and saved: the mean times the
        exposure; (h, w, 4) with alpha when the film is transparent (premultiplied: the camera
        rays that saw the background brought no colour)."""
        image = self.mean(tile)
        if self.exposure != 1.0:
            image = (image * np.float32(self.exposure)).astype(np.float32)
        if self.transparent is None:
            return image
        return np.concatenate([image, self.alpha(tile)[..., None]], axis=-1)

    def alpha(self, tile=None) -> np.ndarray:
        """(h, w) float32 alpha of a transparent film: 1 - the fraction of samples that saw the
        background (1 without samples: nothing was seen through)."""
        s = self._region(tile)
        with np.errstate(invalid="ignore", divide="ignore"):
            a = 1.0 - self.transparent[s] / self.count[s]
        return np.where(self.count[s] > 0, a, 1.0).astype(np.float32)

    def variance_of_mean(self) -> np.ndarray:
        """(h, w, 3) float32 variance of each pixel mean: the sample variance / n (unbiased, n - 1
        in the denominator), at least 2 samples counted.  Computed in float64 and saturated at
        FLOAT32_MAX (radiance of 1e20 and more has a variance beyond float32: never +inf;
        `saturated_variance` counts those pixels)."""
        n = np.maximum(self.count, 2)[..., None]
        mean = self.sum / n
        return np.minimum(np.maximum(self.sum_sq / n - mean * mean, 0.0) / (n - 1), FLOAT32_MAX).astype(np.float32)

    def saturated_variance(self) -> int:
        """Pixels whose variance of the mean is beyond float32 (written as FLOAT32_MAX)."""
        return int((self.variance_of_mean() >= np.float32(FLOAT32_MAX)).any(axis=-1).sum())
