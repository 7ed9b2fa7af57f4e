"""Musgrave Texture (ShaderNodeTexMusgrave) of Blender 3.x-4.0 as Cycles computes it
(intern/cycles/kernel/svm/musgrave.h; Blender 4.1 moved its five types into the Noise Texture,
engine/nodes/procedural/noise.py).  Props: "musgrave_dimensions" ("1D".."4D"), "musgrave_type"
(FBM, MULTIFRACTAL, RIDGED_MULTIFRACTAL, HYBRID_MULTIFRACTAL, HETERO_TERRAIN); inputs Scale,
Detail, Dimension, Lacunarity, Offset, Gain."""
from __future__ import annotations

import numpy as np

from .common import choice, dims_of, out_float, points, scalar, vector, version_of
from .noise import NOISE_TYPES, point_of
from .perlin import F32, snoise


def musgrave_texture(inputs: dict, props: dict, ctx) -> dict:
    """Musgrave Texture of Blender 3.x-4.0 (`svm_node_tex_musgrave`): octaves `i < (int)detail`,
    each octave's amplitude lacunarity^-Dimension."""
    n = points(inputs, ctx)
    version = version_of(ctx)
    dims = dims_of(props, "musgrave_dimensions", "Musgrave Texture")
    kind = choice(props, "musgrave_type", NOISE_TYPES, "FBM", "Musgrave Texture")
    scale = scalar(inputs, "Scale", n, 5.0)
    vec = tuple(c * scale for c in vector(inputs, "Vector", n))
    w = scalar(inputs, "W", n, 0.0) * scale
    dimension = np.maximum(scalar(inputs, "Dimension", n, 2.0), F32(1e-5))
    detail = np.clip(scalar(inputs, "Detail", n, 2.0), F32(0.0), F32(15.0))
    lac = np.maximum(scalar(inputs, "Lacunarity", n, 2.0), F32(1e-5))
    offset = scalar(inputs, "Offset", n, 0.0)
    gain = scalar(inputs, "Gain", n, 1.0)
    p = point_of(dims, vec, w)
    pwhl = np.power(lac, -dimension).astype(F32)
    fac = musgrave(kind, p, pwhl, lac, detail, offset, gain, version)
    return {"Fac": out_float(fac)}


def musgrave(kind, p, pwhl, lac, octaves, offset, gain, version=(3, 4)):
    """Cycles 3.x's `noise_musgrave_*`: like the 4.1+ types with roughness = lacunarity^-H and
    one octave fewer (loops `i < (int)octaves`); fBM is not normalised."""
    n = octaves.astype(np.int64)
    top = int(n.max()) if n.size else 0
    rmd = octaves - np.floor(octaves)
    some_rmd = bool((rmd != 0).any())

    def active(i):
        a = i < n
        return True if a.all() else a

    def upd(a, new, old):
        return new if a is True else np.where(a, new, old)

    def step(q, a):
        return tuple(upd(a, c * lac, c) for c in q)

    if kind == "FBM":
        value, pwr = np.zeros_like(octaves), np.ones_like(octaves)
        for i in range(top):
            a = active(i)
            value = upd(a, value + snoise(p, version) * pwr, value)
            pwr = upd(a, pwr * pwhl, pwr)
            p = step(p, a)
        if some_rmd:
            value = np.where(rmd != 0, value + rmd * snoise(p, version) * pwr, value)
        return value
    if kind == "MULTIFRACTAL":
        value, pwr = np.ones_like(octaves), np.ones_like(octaves)
        for i in range(top):
            a = active(i)
            value = upd(a, value * (pwr * snoise(p, version) + F32(1.0)), value)
            pwr = upd(a, pwr * pwhl, pwr)
            p = step(p, a)
        if some_rmd:
            value = np.where(rmd != 0, value * (rmd * pwr * snoise(p, version) + F32(1.0)), value)
        return value
    if kind == "HETERO_TERRAIN":
        pwr = pwhl
        value = offset + snoise(p, version)
        p = tuple(c * lac for c in p)
        for i in range(1, top):
            a = active(i)
            inc = (snoise(p, version) + offset) * pwr * value
            value = upd(a, value + inc, value)
            pwr = upd(a, pwr * pwhl, pwr)
            p = step(p, a)
        if some_rmd:
            inc = (snoise(p, version) + offset) * pwr * value
            value = np.where(rmd != 0, value + rmd * inc, value)
        return value
    if kind == "HYBRID_MULTIFRACTAL":
        pwr, value, weight = np.ones_like(octaves), np.zeros_like(octaves), np.ones_like(octaves)
        for i in range(top):
            a = (weight > F32(0.001)) & (i < n)
            if not a.any():
                break
            weight = np.where(a, np.minimum(weight, F32(1.0)), weight)
            signal = (snoise(p, version) + offset) * pwr
            pwr = np.where(a, pwr * pwhl, pwr)
            value = np.where(a, value + weight * signal, value)
            weight = np.where(a, weight * (gain * signal), weight)
            p = tuple(np.where(a, c * lac, c) for c in p)
        last = (rmd != 0) & (weight > F32(0.001))
        if last.any():
            signal = (snoise(p, version) + offset) * pwr
            value = np.where(last, value + rmd * np.minimum(weight, F32(1.0)) * signal, value)
        return value
    if kind == "RIDGED_MULTIFRACTAL":
        pwr = pwhl
        signal = offset - np.abs(snoise(p, version))
        signal = signal * signal
        value = signal
        for i in range(1, top):
            a = active(i)
            p = step(p, a)
            weight = np.clip(signal * gain, F32(0.0), F32(1.0))
            s = offset - np.abs(snoise(p, version))
            s = s * s * weight
            value = upd(a, value + s * pwr, value)
            signal = upd(a, s, signal)
            pwr = upd(a, pwr * pwhl, pwr)
        return value
    raise AssertionError(kind)


KERNELS = {"ShaderNodeTexMusgrave": musgrave_texture}
