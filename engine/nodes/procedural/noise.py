"""Noise Texture (ShaderNodeTexNoise) as Cycles computes it (intern/cycles/kernel/svm/noisetex.h,
fractal_noise.h).

Versions (ctx.cycles_version):
- 3.x: fBM of unsigned noise, lacunarity 2, always normalised; inputs Scale, Detail, Roughness,
  Distortion.
- 4.0: + Lacunarity and the `normalize` property (signed octaves, roughness clamped to [0, 1]).
- 4.1+: + `noise_type` (Musgrave's five types moved in: FBM, MULTIFRACTAL, RIDGED_MULTIFRACTAL,
  HYBRID_MULTIFRACTAL, HETERO_TERRAIN) with Offset and Gain; roughness only clamped below at 0.
- 4.2+: Perlin coordinates wrap at 100000 (engine/nodes/procedural/perlin.py).
Props: "noise_dimensions" ("1D".."4D"), "noise_type", "normalize" (Blender 3.x-4.0's Musgrave
Texture: engine/nodes/procedural/musgrave.py).  Distortion and the Color output use fixed random offsets in [100, 200] per
dimension, as Cycles' `random_float{,2,3,4}_offset`.
"""
from __future__ import annotations

import numpy as np

from . import fractal
from .common import (choice, dims_of, out_float, out_rows, points, scalar, vector,
                                            version_of, wanted)
from .hash import hash_float_n_to_float
from .perlin import F32, shifted, snoise

NOISE_TYPES = ("FBM", "MULTIFRACTAL", "RIDGED_MULTIFRACTAL", "HYBRID_MULTIFRACTAL", "HETERO_TERRAIN")


def random_offset(seed: float, dims: int) -> tuple:
    """`random_float{,2,3,4}_offset(seed)`: one offset in [100, 200] per dimension."""
    s = np.array([seed], dtype=F32)
    if dims == 1:
        return (F32(100.0) + hash_float_n_to_float(s)[0] * F32(100.0),)
    return tuple(F32(100.0) + hash_float_n_to_float(s, np.array([i], dtype=F32))[0] * F32(100.0)
                 for i in range(dims))


def point_of(dims, vec, w):
    x, y, z = vec
    return {1: (w,), 2: (x, y), 3: (x, y, z), 4: (x, y, z, w)}[dims]


def _distort(p, distortion, version):
    if not (distortion != 0).any():
        return p
    dims = len(p)
    moved = tuple(c + snoise(shifted(p, random_offset(float(i), dims)), version) * distortion
                  for i, c in enumerate(p))
    return tuple(np.where(distortion != 0, m, c) for m, c in zip(moved, p))


def _texture(p, fn, distortion, version, color):
    """Value and (if ``color``) Color of a Noise-like texture whose fractal is ``fn(point)``."""
    dims = len(p)
    p = _distort(p, distortion, version)
    value = fn(p)
    if not color:
        return value, None
    return value, (value, fn(shifted(p, random_offset(float(dims), dims))),
                   fn(shifted(p, random_offset(float(dims + 1), dims))))


def noise_texture(inputs: dict, props: dict, ctx) -> dict:
    n = points(inputs, ctx)
    version = version_of(ctx)
    dims = dims_of(props, "noise_dimensions", "Noise Texture")
    scale = scalar(inputs, "Scale", n, 5.0)
    vec = tuple(c * scale for c in vector(inputs, "Vector", n))
    w = scalar(inputs, "W", n, 0.0) * scale
    detail = scalar(inputs, "Detail", n, 2.0)
    rough = scalar(inputs, "Roughness", n, 0.5)
    distortion = scalar(inputs, "Distortion", n, 0.0)
    p = point_of(dims, vec, w)
    if version < (4, 0):
        def fn(q):
            return fractal.fractal_noise_legacy(q, detail, rough, version)
    else:
        lac = scalar(inputs, "Lacunarity", n, 2.0)
        detail = np.clip(detail, F32(0.0), F32(15.0))
        if version < (4, 1):
            rough = np.clip(rough, F32(0.0), F32(1.0))
            kind = "FBM"
        else:
            rough = np.maximum(rough, F32(0.0))
            kind = choice(props, "noise_type", NOISE_TYPES, "FBM", "Noise Texture")
        normalize = bool(props.get("normalize", True))
        offset = scalar(inputs, "Offset", n, 0.0)
        gain = scalar(inputs, "Gain", n, 1.0)
        fn = _select(kind, detail, rough, lac, offset, gain, normalize, version)
    value, color = _texture(p, fn, distortion, version, wanted(ctx, "Color"))
    out = {"Fac": out_float(value)}
    if color is not None:
        out["Color"] = out_rows(*color)
    return out


def _select(kind, detail, rough, lac, offset, gain, normalize, version):
    """`noise_select` of Cycles 4.1+: the fractal of the node's noise type, as a function of p."""
    if kind == "FBM":
        return lambda q: fractal.fbm(q, detail, rough, lac, normalize, version)
    if kind == "MULTIFRACTAL":
        return lambda q: fractal.multi_fractal(q, detail, rough, lac, version)
    if kind == "RIDGED_MULTIFRACTAL":
        return lambda q: fractal.ridged_multi_fractal(q, detail, rough, lac, offset, gain, version)
    if kind == "HYBRID_MULTIFRACTAL":
        return lambda q: fractal.hybrid_multi_fractal(q, detail, rough, lac, offset, gain, version)
    if kind == "HETERO_TERRAIN":
        return lambda q: fractal.hetero_terrain(q, detail, rough, lac, offset, version)
    raise AssertionError(kind)


KERNELS = {"ShaderNodeTexNoise": noise_texture}
