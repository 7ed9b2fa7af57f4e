"""Cycles' integer and float hashes (intern/cycles/util/hash.h), bit-exact in uint32/int32.

Every procedural texture of Cycles draws its randomness from these: Bob Jenkins' lookup3
(`hash_uint` .. `hash_uint4`, used on the bit patterns of float32 coordinates by Perlin noise,
White Noise and 1-D Voronoi) and the PCG hashes of "Hash Functions for GPU Rendering" (JCGT 2020,
`hash_pcg2d_i` .. `hash_pcg4d_i`, used on integer cells by 2-D to 4-D Voronoi since Blender 4.0).
Blender 3.4's Voronoi hashed float cell positions with lookup3 instead (`hash_float*_to_float*`).

Arrays in, arrays out: uint32 or int32 arithmetic wraps like C's (NumPy does not warn on array
overflow); floats are float32, as Cycles computes them.
"""
from __future__ import annotations

import numpy as np

U32 = np.uint32
F32 = np.float32
_SEED = 0xDEADBEEF


def as_u32(k) -> np.ndarray:
    """An integer array as uint32 (C's conversion of int to uint: modulo 2^32)."""
    k = np.asarray(k)
    if k.dtype == np.uint32:
        return k
    return k.astype(np.int64).astype(np.uint32)


def float_bits(x) -> np.ndarray:
    """`__float_as_uint`: the bit pattern of float32 values."""
    return np.ascontiguousarray(np.asarray(x, dtype=F32)).view(U32)


def _rot(x, k):
    return (x << U32(k)) | (x >> U32(32 - k))


def _mix(a, b, c):
    a = a - c; a ^= _rot(c, 4); c = c + b          # noqa: E702
    b = b - a; b ^= _rot(a, 6); a = a + c          # noqa: E702
    c = c - b; c ^= _rot(b, 8); b = b + a          # noqa: E702
    a = a - c; a ^= _rot(c, 16); c = c + b         # noqa: E702
    b = b - a; b ^= _rot(a, 19); a = a + c         # noqa: E702
    c = c - b; c ^= _rot(b, 4); b = b + a          # noqa: E702
    return a, b, c


def _final(a, b, c):
    c ^= b; c = c - _rot(b, 14)                    # noqa: E702
    a ^= c; a = a - _rot(c, 11)                    # noqa: E702
    b ^= a; b = b - _rot(a, 25)                    # noqa: E702
    c ^= b; c = c - _rot(b, 16)                    # noqa: E702
    a ^= c; a = a - _rot(c, 4)                     # noqa: E702
    b ^= a; b = b - _rot(a, 14)                    # noqa: E702
    c ^= b; c = c - _rot(b, 24)                    # noqa: E702
    return c


def _start(n_words):
    """lookup3's initial a = b = c for ``n_words`` words (a uint32 scalar)."""
    return U32((_SEED + (n_words << 2) + 13) & 0xFFFFFFFF)


def hash_uint(kx) -> np.ndarray:
    kx = as_u32(kx)
    s = _start(1)
    return _final(kx + s, np.full_like(kx, s), np.full_like(kx, s))


def hash_uint2(kx, ky) -> np.ndarray:
    kx, ky = np.broadcast_arrays(as_u32(kx), as_u32(ky))
    s = _start(2)
    return _final(kx + s, ky + s, np.full_like(kx, s))


def hash_uint3(kx, ky, kz) -> np.ndarray:
    kx, ky, kz = np.broadcast_arrays(as_u32(kx), as_u32(ky), as_u32(kz))
    s = _start(3)
    return _final(kx + s, ky + s, kz + s)


def hash_uint4(kx, ky, kz, kw) -> np.ndarray:
    kx, ky, kz, kw = np.broadcast_arrays(as_u32(kx), as_u32(ky), as_u32(kz), as_u32(kw))
    s = _start(4)
    a, b, c = _mix(kx + s, ky + s, kz + s)
    return _final(a + kw, b, c)


_HASH_UINT = {1: hash_uint, 2: hash_uint2, 3: hash_uint3, 4: hash_uint4}


def hash_uint_n(*ks) -> np.ndarray:
    """lookup3 of 1 to 4 words."""
    return _HASH_UINT[len(ks)](*ks)


def uint_to_float_incl(n) -> np.ndarray:
    """[0, 2^32 - 1] -> [0, 1]: (float)n * (1.0f / (float)0xFFFFFFFFu), i.e. float32(n) * 2^-32."""
    return np.asarray(n).astype(F32) * F32(1.0 / 4294967296.0)


def hash_float_n_to_float(*ks) -> np.ndarray:
    """`hash_float{,2,3,4}_to_float`: lookup3 of the float32 bit patterns, in [0, 1]."""
    return uint_to_float_incl(hash_uint_n(*(float_bits(k) for k in ks)))


def _f(v):
    return F32(v)


def hash_float_to_float3(k):
    return (hash_float_n_to_float(k), hash_float_n_to_float(k, _f(1.0)),
            hash_float_n_to_float(k, _f(2.0)))


def hash_float2_to_float2(x, y):
    return hash_float_n_to_float(x, y), hash_float_n_to_float(x, y, _f(1.0))


def hash_float2_to_float3(x, y):
    return (hash_float_n_to_float(x, y), hash_float_n_to_float(x, y, _f(1.0)),
            hash_float_n_to_float(x, y, _f(2.0)))


def hash_float3_to_float3(x, y, z):
    return (hash_float_n_to_float(x, y, z), hash_float_n_to_float(x, y, z, _f(1.0)),
            hash_float_n_to_float(x, y, z, _f(2.0)))


def hash_float4_to_float4(x, y, z, w):
    return (hash_float_n_to_float(x, y, z, w), hash_float_n_to_float(w, x, y, z),
            hash_float_n_to_float(z, w, x, y), hash_float_n_to_float(y, z, w, x))


def hash_float4_to_float3(x, y, z, w):
    return (hash_float_n_to_float(x, y, z, w), hash_float_n_to_float(z, x, w, y),
            hash_float_n_to_float(w, z, y, x))


# -- PCG (signed-integer variant of Cycles, so that OSL can run it too) -------------------------

_PCG_MUL = np.int32(1664525)
_PCG_ADD = np.int32(1013904223)


def _i32(k):
    return np.asarray(k).astype(np.int64).astype(np.int32)


def hash_pcg2d_i(x, y):
    x, y = np.broadcast_arrays(_i32(x), _i32(y))
    x = x * _PCG_MUL + _PCG_ADD
    y = y * _PCG_MUL + _PCG_ADD
    x = x + y * _PCG_MUL
    y = y + x * _PCG_MUL
    x = x ^ (x >> 16)
    y = y ^ (y >> 16)
    x = x + y * _PCG_MUL
    y = y + x * _PCG_MUL
    return x & np.int32(0x7FFFFFFF), y & np.int32(0x7FFFFFFF)


def hash_pcg3d_i(x, y, z):
    x, y, z = np.broadcast_arrays(_i32(x), _i32(y), _i32(z))
    x = x * _PCG_MUL + _PCG_ADD
    y = y * _PCG_MUL + _PCG_ADD
    z = z * _PCG_MUL + _PCG_ADD
    x = x + y * z
    y = y + z * x
    z = z + x * y
    x, y, z = x ^ (x >> 16), y ^ (y >> 16), z ^ (z >> 16)
    x = x + y * z
    y = y + z * x
    z = z + x * y
    m = np.int32(0x7FFFFFFF)
    return x & m, y & m, z & m


def hash_pcg4d_i(x, y, z, w):
    x, y, z, w = np.broadcast_arrays(_i32(x), _i32(y), _i32(z), _i32(w))
    x = x * _PCG_MUL + _PCG_ADD
    y = y * _PCG_MUL + _PCG_ADD
    z = z * _PCG_MUL + _PCG_ADD
    w = w * _PCG_MUL + _PCG_ADD
    x = x + y * w
    y = y + z * x
    z = z + x * y
    w = w + y * z
    x, y, z, w = x ^ (x >> 16), y ^ (y >> 16), z ^ (z >> 16), w ^ (w >> 16)
    x = x + y * w
    y = y + z * x
    z = z + x * y
    w = w + y * z
    m = np.int32(0x7FFFFFFF)
    return x & m, y & m, z & m, w & m


def _to_unit(h):
    """int in [0, 2^31 - 1] -> [0, 1]: (float)h * (1.0f / (float)0x7FFFFFFFu) = float32(h) * 2^-31."""
    return h.astype(F32) * F32(1.0 / 2147483648.0)


_PCG = {2: hash_pcg2d_i, 3: hash_pcg3d_i, 4: hash_pcg4d_i}


def hash_int_n_to_float_n(*ks):
    """`hash_int{2,3,4}_to_float{2,3,4}`: PCG of integer cells, each component in [0, 1]."""
    return tuple(_to_unit(h) for h in _PCG[len(ks)](*ks))


def hash_int_n_to_float3(*ks):
    """`hash_int{2,3,4}_to_float3` (2-D pads z = 0 and hashes in 3-D; 4-D drops w)."""
    if len(ks) == 2:
        ks = (ks[0], ks[1], np.zeros_like(_i32(ks[0])))
    return hash_int_n_to_float_n(*ks)[:3]
