"""engine/sampling/qmc.py `sample_2d` compiled with numba: the index shuffle, the second Sobol'
dimension, the Owen scrambles and the bit reversals of each point in one loop over the paths.
Integer arithmetic on int64 holding 32-bit values (products wrap modulo 2^64 and are masked to
32 bits, as NumPy's uint32 products wrap), so the points are the same bit for bit
(tests/sampling/test_sobol_jit.py).  Imported only through engine/core/backend.py's choice."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from .qmc import _DIM_HASHES, _DIM_SALT, _KEY_SALTS, _dim_hash

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

M32 = 0xFFFFFFFF
SALT0, SALT1, SALT2 = (int(s) for s in _KEY_SALTS)
TO_UNIT = 1.0 / 4294967296.0
DIM_SALT = int(_DIM_SALT)
DIM_HASHES = np.ascontiguousarray(_DIM_HASHES, np.uint32)     # hash32(dim + DIM_SALT) of dims below 1024


@jit
def _hash32(x):
    x ^= x >> 16
    x = (x * 0x7FEB352D) & M32
    x ^= x >> 15
    x = (x * 0x846CA68B) & M32
    x ^= x >> 16
    return x


@jit
def _reverse_bits(x):
    x = ((x >> 1) & 0x55555555) | ((x & 0x55555555) << 1)
    x = ((x >> 2) & 0x33333333) | ((x & 0x33333333) << 2)
    x = ((x >> 4) & 0x0F0F0F0F) | ((x & 0x0F0F0F0F) << 4)
    x = ((x >> 8) & 0x00FF00FF) | ((x & 0x00FF00FF) << 8)
    return ((x >> 16) & 0xFFFF) | ((x & 0xFFFF) << 16)


@jit
def _dim1_reversed(w):
    w ^= (w >> 1) & 0x55555555
    w ^= (w >> 2) & 0x33333333
    w ^= (w >> 4) & 0x0F0F0F0F
    w ^= (w >> 8) & 0x00FF00FF
    w ^= (w >> 16) & 0x0000FFFF
    return w


@jit
def _laine_karras(x, seed):
    x = (x + seed) & M32
    x ^= (x * 0x6C50B47C) & M32
    x ^= (x * 0xB82F1E52) & M32
    x ^= (x * 0xC7AFE638) & M32
    x ^= (x * 0x8D22F6E6) & M32
    return x


@jit
def _permute(index, bits, key):
    if bits == 0:
        return 0
    mask = (1 << bits) - 1
    shift = max(1, (bits + 1) // 2)
    x = index & mask
    x = (x ^ key) & mask
    x = (x * 0x2C1B3C6D) & mask
    x ^= x >> shift
    x = (x ^ (key >> 11)) & mask
    x = (x * 0x297A2D39) & mask
    x ^= x >> shift
    x = (x ^ (key >> 22)) & mask
    x = (x * 0x9E3779B9) & mask
    x ^= x >> shift
    return x


@jit
def _sample_2d(index, pixel_seed, dim_hash, bits):
    n = index.shape[0]
    each = dim_hash.shape[0] > 1
    x_out = np.empty(n, np.float64)
    y_out = np.empty(n, np.float64)
    for k in range(n):
        seed = _hash32(np.int64(pixel_seed[k]) ^ np.int64(dim_hash[k if each else 0]))
        i = _permute(np.int64(index[k]), bits, _hash32(SALT0 ^ seed))
        x_out[k] = _reverse_bits(_laine_karras(i, _hash32(SALT1 ^ seed))) * TO_UNIT
        y_out[k] = _reverse_bits(_laine_karras(_dim1_reversed(i), _hash32(SALT2 ^ seed))) * TO_UNIT
    return x_out, y_out


@jit
def _sample_2d_seeded(index, pixel, seed_table, dim, dim_table, bits):
    n = index.shape[0]
    each = dim.shape[0] > 1
    x_out = np.empty(n, np.float64)
    y_out = np.empty(n, np.float64)
    for k in range(n):
        dk = dim[k if each else 0]
        dim_hash = dim_table[dk] if 0 <= dk < dim_table.shape[0] else _hash32((dk + DIM_SALT) & M32)
        seed = _hash32(np.int64(seed_table[pixel[k]]) ^ np.int64(dim_hash))
        i = _permute(index[k] & M32, bits, _hash32(SALT0 ^ seed))
        x_out[k] = _reverse_bits(_laine_karras(i, _hash32(SALT1 ^ seed))) * TO_UNIT
        y_out[k] = _reverse_bits(_laine_karras(_dim1_reversed(i), _hash32(SALT2 ^ seed))) * TO_UNIT
    return x_out, y_out


def _int64(a):
    a = np.asarray(a)
    return a if a.dtype == np.int64 and a.flags.c_contiguous else np.ascontiguousarray(a, np.int64)


def sample_2d_seeded(index, pixel, seed_table, dim, count: int = 1 << 16):
    """sample_2d(index, seed_table.take(pixel), dim, count) without the gather: each path's pixel seed
    and dimension hash are read inside the loop (qmc.SobolSampler.pair's compiled form)."""
    bits = max(int(count - 1).bit_length(), 0)
    index, pixel = _int64(index).reshape(-1), _int64(pixel).reshape(-1)
    return _sample_2d_seeded(index, pixel, seed_table, _int64(dim).reshape(-1), DIM_HASHES, bits)


def sample_2d(index, pixel_seed, dim, count: int = 1 << 16):
    """As qmc.sample_2d (index and pixel_seed (N,) arrays; dim an int or (N,))."""
    bits = max(int(count - 1).bit_length(), 0)
    index = np.ascontiguousarray(index, np.uint32).reshape(-1)
    pixel_seed = np.ascontiguousarray(np.broadcast_to(np.asarray(pixel_seed, np.uint32), index.shape))
    dim_hash = np.ascontiguousarray(np.asarray(_dim_hash(dim), np.uint32).reshape(-1))
    return _sample_2d(index, pixel_seed, dim_hash, bits)


def warm_up() -> None:
    """Compile (or load) the kernel for the types a render passes."""
    sample_2d(np.arange(4), np.arange(4, dtype=np.uint32), 3, 16)
    sample_2d(np.arange(4), np.arange(4, dtype=np.uint32), np.arange(4), 16)
    sample_2d_seeded(np.arange(4), np.arange(4), np.arange(4, dtype=np.uint32), 3, 16)
    sample_2d_seeded(np.arange(4), np.arange(4), np.arange(4, dtype=np.uint32), np.arange(4), 16)
