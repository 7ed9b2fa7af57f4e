"""Image files: EXR and PNG written atomically and checked, and read back.

Rows are stored top-down.  EXR is linear float; PNG is sRGB-encoded and clipped.  An (H, W, 4)
image is premultiplied RGBA (a transparent film): the EXR keeps it so (as Blender's), the PNG stores
straight alpha (as Blender saves PNGs: the colour divided by alpha before the sRGB encoding).
"""
from __future__ import annotations

import numpy as np


def linear_to_srgb(image: np.ndarray) -> np.ndarray:
    x = np.clip(image, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def _write_checked(path: str, pixels: np.ndarray, pixel_type: str, attributes=(), channel_names=None) -> None:
    """One image through OpenImageIO, every step checked: a full disk or a failed write raises
    OSError instead of leaving a truncated file behind a success (OIIO's PNG writer reports
    short writes only through geterror())."""
    import OpenImageIO as oiio
    pixels = np.ascontiguousarray(pixels)
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise OSError(f"no image writer for '{path}': {oiio.geterror()}")
    spec = oiio.ImageSpec(w, h, c, pixel_type)
    if channel_names is not None:
        spec.channelnames = tuple(channel_names)
    for name, value in attributes:
        spec.attribute(name, value)
    if not out.open(str(path), spec):
        raise OSError(out.geterror() or oiio.geterror())
    written = out.write_image(pixels)
    error = out.geterror()
    closed = out.close()
    error = error or out.geterror()
    if not (written and closed) or error:
        raise OSError(error.strip().splitlines()[0] if error else "image write failed")


def write_exr(path: str, image: np.ndarray, metadata=()) -> None:
    """metadata: (name, value) header attributes, e.g. the error estimate (engine/cli/main.py)."""
    _write_checked(path, np.asarray(image, dtype=np.float32), "float", [("compression", "zip"), *metadata])


def write_png(path: str, image: np.ndarray) -> None:
    image = np.asarray(image)
    if image.shape[-1] != 4:
        _write_checked(path, (linear_to_srgb(image) * 255.0 + 0.5).astype(np.uint8), "uint8")
        return
    alpha = np.clip(image[..., 3:4], 0.0, 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        straight = np.where(alpha > 0.0, image[..., :3] / alpha, 0.0)
    pixels = np.concatenate([linear_to_srgb(straight), alpha], axis=-1)
    # OpenImageIO would divide by alpha again unless told the pixels are straight already
    _write_checked(path, (pixels * 255.0 + 0.5).astype(np.uint8), "uint8", [("oiio:UnassociatedAlpha", 1)])


def read_image(path: str) -> np.ndarray:
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise OSError(f"cannot read '{path}': {oiio.geterror()}")
    pixels = inp.read_image("float")
    inp.close()
    return np.asarray(pixels, dtype=np.float32)
