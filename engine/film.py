"""Film: per-pixel radiance sums and variance, and image files.

Pixels use a box filter (every sample counts fully in the pixel it falls in).
Rows are stored top-down.  EXR is linear float; PNG is sRGB-encoded and clipped.
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


def linear_to_srgb(image: np.ndarray) -> np.ndarray:
    x = np.clip(image, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def write_exr(path: str, image: np.ndarray) -> None:
    import OpenImageIO as oiio
    image = np.ascontiguousarray(image, dtype=np.float32)
    h, w, c = image.shape
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise OSError(f"cannot write '{path}': {oiio.geterror()}")
    spec = oiio.ImageSpec(w, h, c, "float")
    spec.attribute("compression", "zip")
    if not out.open(str(path), spec):
        raise OSError(f"cannot write '{path}': {out.geterror()}")
    out.write_image(image)
    out.close()


def write_png(path: str, image: np.ndarray) -> None:
    import OpenImageIO as oiio
    encoded = (linear_to_srgb(image) * 255.0 + 0.5).astype(np.uint8)
    h, w, c = encoded.shape
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), oiio.ImageSpec(w, h, c, "uint8")):
        raise OSError(f"cannot write '{path}': {oiio.geterror()}")
    out.write_image(np.ascontiguousarray(encoded))
    out.close()


def write_image(path: str, image: np.ndarray) -> None:
    """EXR for .exr (linear), PNG otherwise (sRGB)."""
    if str(path).lower().endswith(".exr"):
        write_exr(path, image)
    else:
        write_png(path, image)


def read_image(path: str) -> np.ndarray:
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise OSError(f"cannot read '{path}': {oiio.geterror()}")
    pixels = inp.read_image("float")
    inp.close()
    return np.asarray(pixels, dtype=np.float32)
