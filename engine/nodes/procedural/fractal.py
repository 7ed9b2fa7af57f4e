"""Fractal sums of Perlin noise (intern/cycles/kernel/svm/fractal_noise.h, 4.x/5.0, and the
fractal_noise_{D}d of Blender 3.x), over per-point parameter arrays.

Cycles loops `for (i = 0; i <= (int)detail; i++)` per shading point; here the loop runs to the
largest octave count of the batch and each point stops adding where its own count ends (a mask),
so linked Detail/Roughness/Lacunarity sockets give the same result as Cycles, point by point.
All arithmetic is float32.
"""
from __future__ import annotations

import numpy as np

from .perlin import F32, mix, scaled, snoise, unoise


def _octaves(detail):
    n = detail.astype(np.int64)                     # float_to_int: truncation, detail >= 0
    return n, int(n.max()) if n.size else 0


def _upd(active, new, old):
    return new if active is True else np.where(active, new, old)


def _active(i, n):
    act = i <= n
    return True if act.all() else act


def fbm(p, detail, roughness, lacunarity, normalize, version=(5, 0)):
    """`noise_fbm` (Blender 4.0+): signed octaves, optional normalisation to [0, 1]."""
    n, top = _octaves(detail)
    one = np.ones_like(detail)
    fscale, amp, maxamp, total = one, one, np.zeros_like(detail), np.zeros_like(detail)
    for i in range(top + 1):
        act = _active(i, n)
        t = snoise(scaled(p, fscale), version)
        total = _upd(act, total + t * amp, total)
        maxamp = _upd(act, maxamp + amp, maxamp)
        amp = _upd(act, amp * roughness, amp)
        fscale = _upd(act, fscale * lacunarity, fscale)
    rmd = detail - np.floor(detail)
    if normalize:
        whole = F32(0.5) * total / maxamp + F32(0.5)
    else:
        whole = total
    if not (rmd != 0).any():
        return whole
    t = snoise(scaled(p, fscale), version)
    total2 = total + t * amp
    if normalize:
        part = mix(whole, F32(0.5) * total2 / (maxamp + amp) + F32(0.5), rmd)
    else:
        part = mix(total, total2, rmd)
    return np.where(rmd != 0, part, whole)


def fractal_noise_legacy(p, octaves, roughness, version=(3, 4)):
    """Blender 3.x's `fractal_noise_{D}d`: unsigned octaves, lacunarity 2, always normalised."""
    octaves = np.clip(octaves, F32(0.0), F32(15.0))
    n, top = _octaves(octaves)
    rough = np.clip(roughness, F32(0.0), F32(1.0))
    one = np.ones_like(octaves)
    fscale, amp, maxamp, total = one, one, np.zeros_like(octaves), np.zeros_like(octaves)
    for i in range(top + 1):
        act = _active(i, n)
        t = unoise(scaled(p, fscale), version)
        total = _upd(act, total + t * amp, total)
        maxamp = _upd(act, maxamp + amp, maxamp)
        amp = _upd(act, amp * rough, amp)
        fscale = _upd(act, fscale * F32(2.0), fscale)
    rmd = octaves - np.floor(octaves)
    whole = total / maxamp
    if not (rmd != 0).any():
        return whole
    t = unoise(scaled(p, fscale), version)
    total2 = (total + t * amp) / (maxamp + amp)
    return np.where(rmd != 0, (F32(1.0) - rmd) * whole + rmd * total2, whole)


def multi_fractal(p, detail, roughness, lacunarity, version=(5, 0)):
    n, top = _octaves(detail)
    value = np.ones_like(detail)
    pwr = np.ones_like(detail)
    for i in range(top + 1):
        act = _active(i, n)
        value = _upd(act, value * (pwr * snoise(p, version) + F32(1.0)), value)
        pwr = _upd(act, pwr * roughness, pwr)
        p = tuple(_upd(act, c * lacunarity, c) for c in p)
    rmd = detail - np.floor(detail)
    if (rmd != 0).any():
        value = np.where(rmd != 0, value * (rmd * pwr * snoise(p, version) + F32(1.0)), value)
    return value


def hetero_terrain(p, detail, roughness, lacunarity, offset, version=(5, 0)):
    n, top = _octaves(detail)
    pwr = roughness
    value = offset + snoise(p, version)
    p = scaled(p, lacunarity)
    for i in range(1, top + 1):
        act = _active(i, n)
        increment = (snoise(p, version) + offset) * pwr * value
        value = _upd(act, value + increment, value)
        pwr = _upd(act, pwr * roughness, pwr)
        p = tuple(_upd(act, c * lacunarity, c) for c in p)
    rmd = detail - np.floor(detail)
    if (rmd != 0).any():
        increment = (snoise(p, version) + offset) * pwr * value
        value = np.where(rmd != 0, value + rmd * increment, value)
    return value


def hybrid_multi_fractal(p, detail, roughness, lacunarity, offset, gain, version=(5, 0)):
    n, top = _octaves(detail)
    pwr = np.ones_like(detail)
    value = np.zeros_like(detail)
    weight = np.ones_like(detail)
    for i in range(top + 1):
        act = (weight > F32(0.001)) & (i <= n)
        if not act.any():
            break
        weight = np.where(act, np.minimum(weight, F32(1.0)), weight)
        signal = (snoise(p, version) + offset) * pwr
        pwr = np.where(act, pwr * roughness, pwr)
        value = np.where(act, value + weight * signal, value)
        weight = np.where(act, weight * (gain * signal), weight)
        p = tuple(np.where(act, c * lacunarity, c) for c in p)
    rmd = detail - np.floor(detail)
    last = (rmd != 0) & (weight > F32(0.001))
    if last.any():
        w = np.minimum(weight, F32(1.0))
        signal = (snoise(p, version) + offset) * pwr
        value = np.where(last, value + rmd * w * signal, value)
    return value


def ridged_multi_fractal(p, detail, roughness, lacunarity, offset, gain, version=(5, 0)):
    n, top = _octaves(detail)
    pwr = roughness
    signal = offset - np.abs(snoise(p, version))
    signal = signal * signal
    value = signal
    for i in range(1, top + 1):
        act = _active(i, n)
        p = tuple(_upd(act, c * lacunarity, c) for c in p)
        weight = np.clip(signal * gain, F32(0.0), F32(1.0))
        s = offset - np.abs(snoise(p, version))
        s = s * s * weight
        value = _upd(act, value + s * pwr, value)
        signal = _upd(act, s, signal)
        pwr = _upd(act, pwr * roughness, pwr)
    return value
