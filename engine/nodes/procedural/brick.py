"""Brick Texture (ShaderNodeTexBrick) as Cycles' `svm_brick` (intern/cycles/kernel/svm/brick.h).

Props: "offset" (float), "offset_frequency" (int), "squash" (float), "squash_frequency" (int).
The tint of each brick comes from Cycles' integer `brick_noise` of (row << 16) + (brick & 0xFFFF).
"""
from __future__ import annotations

import numpy as np

from .common import out_float, points, scalar, vector
from .perlin import F32


def brick_noise(n):
    """Cycles' fast integer noise in [0, 1) (uint32 arithmetic)."""
    n = np.asarray(n).astype(np.int64).astype(np.uint32)
    n = (n + np.uint32(1013)) & np.uint32(0x7FFFFFFF)
    n = (n >> np.uint32(13)) ^ n
    nn = (n * (n * n * np.uint32(60493) + np.uint32(19990303)) + np.uint32(1376312589)) \
        & np.uint32(0x7FFFFFFF)
    return F32(0.5) * (nn.astype(F32) / F32(1073741824.0))


def _smoothstepf(f):
    ff = f * f
    return np.where(f <= 0, F32(0.0), np.where(f >= 1, F32(1.0), F32(3.0) * ff - F32(2.0) * ff * f))


def brick(p, mortar_size, mortar_smooth, bias, brick_width, row_height, offset_amount,
          offset_frequency, squash_amount, squash_frequency):
    """(tint, mortar) per point."""
    x0, y0 = p[0], p[1]
    rownum = np.floor(y0 / row_height).astype(np.int64)
    offset = np.zeros_like(x0)
    if offset_frequency and squash_frequency:
        brick_width = brick_width * np.where(rownum % squash_frequency != 0, F32(1.0), F32(squash_amount))
        offset = np.where(rownum % offset_frequency != 0, F32(0.0), brick_width * F32(offset_amount))
    bricknum = np.floor((x0 + offset) / brick_width).astype(np.int64)
    x = (x0 + offset) - brick_width * bricknum.astype(F32)
    y = y0 - row_height * rownum.astype(F32)
    key = ((rownum << 16) + (bricknum & 0xFFFF)) & 0xFFFFFFFF
    tint = np.clip(brick_noise(key) + bias, F32(0.0), F32(1.0))
    min_dist = np.minimum(np.minimum(x, y), np.minimum(brick_width - x, row_height - y))
    with np.errstate(divide="ignore", invalid="ignore"):
        smooth = _smoothstepf((F32(1.0) - min_dist / mortar_size) / mortar_smooth)
    mortar = np.where(min_dist >= mortar_size, F32(0.0),
                      np.where(mortar_smooth == 0, F32(1.0), smooth))
    return tint, mortar


def brick_texture(inputs: dict, props: dict, ctx) -> dict:
    n = points(inputs, ctx)
    scale = scalar(inputs, "Scale", n, 5.0)
    p = tuple(c * scale for c in vector(inputs, "Vector", n))
    tint, f = brick(p, scalar(inputs, "Mortar Size", n, 0.02), scalar(inputs, "Mortar Smooth", n, 0.1),
                    scalar(inputs, "Bias", n, 0.0), scalar(inputs, "Brick Width", n, 0.5),
                    scalar(inputs, "Row Height", n, 0.25), float(props.get("offset", 0.5)),
                    int(props.get("offset_frequency", 2)), float(props.get("squash", 1.0)),
                    int(props.get("squash_frequency", 2)))
    c1 = np.stack(vector(inputs, "Color1", n, (0.8, 0.8, 0.8)))
    c2 = np.stack(vector(inputs, "Color2", n, (0.2, 0.2, 0.2)))
    mortar = np.stack(vector(inputs, "Mortar", n, (0.0, 0.0, 0.0)))
    c1 = np.where(f != F32(1.0), (F32(1.0) - tint) * c1 + tint * c2, c1)
    color = c1 * (F32(1.0) - f) + mortar * f
    return {"Fac": out_float(f), "Color": np.asarray(color, dtype=np.float64)}


KERNELS = {"ShaderNodeTexBrick": brick_texture}
