"""Film of one tile: per-pixel radiance sums, sums of squares and sample counts.

Pixels use a box filter (every sample counts fully in the pixel it falls in).
"""
from __future__ import annotations

import numpy as np


class TileFilm:
    """Accumulates samples of one tile: sum and sum of squares per pixel and channel."""

    def __init__(self, width: int, height: int):
        self.width, self.height = width, height
        n = width * height
        self.sum = np.zeros((n, 3))
        self.sum_sq = np.zeros((n, 3))
        self.count = np.zeros(n)

    def add(self, pixel: np.ndarray, radiance: np.ndarray) -> None:
        """Samples' radiance as rows (3, N) (engine/vec.py) into their pixels."""
        n = self.width * self.height
        self.count += np.bincount(pixel, minlength=n)
        for c in range(3):
            self.sum[:, c] += np.bincount(pixel, weights=radiance[c], minlength=n)
            self.sum_sq[:, c] += np.bincount(pixel, weights=radiance[c] * radiance[c], minlength=n)

    def mean(self) -> np.ndarray:
        with np.errstate(invalid="ignore", divide="ignore"):
            m = self.sum / self.count[:, None]
        return np.nan_to_num(m).reshape(self.height, self.width, 3)

    def variance_of_mean(self) -> np.ndarray:
        """Unbiased per-pixel variance of the pixel estimate (sample variance / n)."""
        n = np.maximum(self.count, 2)[:, None]
        mean = self.sum / n
        var = np.maximum(self.sum_sq / n - mean * mean, 0.0) * n / (n - 1) / n
        return var.reshape(self.height, self.width, 3)
