"""Perlin noise of Cycles (intern/cycles/kernel/svm/noise.h) in 1 to 4 dimensions, float32.

A point is a tuple of D float32 arrays (its coordinates), so that the same code runs 1-D to 4-D.
`perlin(p)` is Cycles' `perlin_{1,2,3,4}d`: lookup3 hashes of the integer lattice corners
(engine/nodes/procedural/hash.py), Ken Perlin's gradient sets `grad1` .. `grad4`, the quintic
fade, and interpolation along x first, then y, z, w (the order of Cycles' SSE/AVX kernels, which
the CPU renderer runs).  `snoise(p, version)` is the signed noise in about [-1, 1] (OSL's
experimental scale per dimension); Blender 4.2 and later wrap every coordinate at 100000 first
(`fmod` and a half-cell shift beyond 10^6), Blender 3.x-4.1 only replace a non-finite result by 0.
"""
from __future__ import annotations

import itertools

import numpy as np

from .hash import hash_uint_n

F32 = np.float32
NOISE_SCALE = {1: F32(0.2500), 2: F32(0.6616), 3: F32(0.9820), 4: F32(0.8344)}
WRAP_SINCE = (4, 2)          # first Blender version whose snoise wraps coordinates at 100000


def f32(x) -> np.ndarray:
    return np.asarray(x, dtype=F32)


def mix(a, b, t):
    """Cycles' `mix`: a + t * (b - a)."""
    return a + t * (b - a)


def _fade(t):
    a = t * F32(6.0) - F32(15.0)
    b = t * a + F32(10.0)
    return (t * t) * (t * b)


def _flip(v, h, bit):
    """-v where bit ``bit`` of the hash ``h`` is set: Cycles' `negate_if_nth_bit`, an XOR of the
    float32 sign bit (exact, like negation)."""
    sign = (h & np.uint32(1 << bit)) << np.uint32(31 - bit)
    return (np.ascontiguousarray(v, dtype=F32).view(np.uint32) ^ sign).view(F32)


def _grad(h, d):
    """Gradient dot offset for the corner hash ``h`` (uint32) and offset ``d`` (D arrays)."""
    if len(d) == 1:
        h = h & np.uint32(15)
        g = ((h & np.uint32(7)) + np.uint32(1)).astype(F32)
        return _flip(g, h, 3) * d[0]
    if len(d) == 2:
        x, y = d
        h = h & np.uint32(7)
        lo = h < 4
        u = np.where(lo, x, y)
        v = F32(2.0) * np.where(lo, y, x)
        return _flip(u, h, 0) + _flip(v, h, 1)
    if len(d) == 3:
        x, y, z = d
        h = h & np.uint32(15)
        u = np.where(h < 8, x, y)
        vt = np.where((h == 12) | (h == 14), x, z)
        v = np.where(h < 4, y, vt)
        return _flip(u, h, 0) + _flip(v, h, 1)
    x, y, z, w = d
    h = h & np.uint32(31)
    u = np.where(h < 24, x, y)
    v = np.where(h < 16, y, z)
    s = np.where(h < 8, z, w)
    return _flip(u, h, 0) + _flip(v, h, 1) + _flip(s, h, 2)


def perlin(p) -> np.ndarray:
    """Cycles' unscaled `perlin_{D}d` at the point ``p`` (tuple of D float32 arrays)."""
    dims = len(p)
    floors = [np.floor(c) for c in p]
    # float_to_int of the floor, as the uint32 that lookup3 hashes (corner + 1 wraps like C's)
    cells = [fl.astype(np.int32).view(np.uint32) for fl in floors]
    frac = [c - fl for c, fl in zip(p, floors)]
    fades = [_fade(t) for t in frac]
    corners = {}
    for corner in itertools.product((0, 1), repeat=dims):
        h = hash_uint_n(*(cell + np.uint32(o) if o else cell for cell, o in zip(cells, corner)))
        corners[corner] = _grad(h, [t - F32(o) for t, o in zip(frac, corner)])
    # Interpolate along x (the first index of a corner) first, then y, z, w.
    for axis in range(dims):
        corners = {rest: mix(corners[(0,) + rest], corners[(1,) + rest], fades[axis])
                   for rest in itertools.product((0, 1), repeat=dims - axis - 1)}
    return corners[()]


def snoise(p, version=(5, 0)) -> np.ndarray:
    """Signed noise `snoise_{D}d` of the Blender ``version`` (major, minor)."""
    dims = len(p)
    if tuple(version) >= WRAP_SINCE:
        p = tuple(np.fmod(c, F32(100000.0)) + F32(0.5) * (np.abs(c) >= F32(1000000.0)).astype(F32)
                  for c in p)
        return NOISE_SCALE[dims] * perlin(p)
    r = perlin(p)
    return NOISE_SCALE[dims] * np.where(np.isfinite(r), r, F32(0.0))


def unoise(p, version=(5, 0)) -> np.ndarray:
    """Unsigned noise `noise_{D}d` in about [0, 1]."""
    return F32(0.5) * snoise(p, version) + F32(0.5)


def scaled(p, s):
    """The point ``p`` times the per-point factor ``s``."""
    return tuple(c * s for c in p)


def shifted(p, offset):
    """The point ``p`` plus the constant offset (one float per dimension)."""
    return tuple(c + F32(o) for c, o in zip(p, offset))
