"""engine/sampling/qmc.py `sample_2d` compiled with numba: the index shuffle, the second Sobol'
dimension, the Owen scrambles and the bit reversals of each point in one loop over the paths.
`sample_2d`: integer arithmetic on int64 holding 32-bit values (products wrap modulo 2^64 and are
masked to 32 bits, as NumPy's uint32 products wrap).  `sample_2d_seeded`, what a render's sampler
calls (qmc.SobolSampler.pair): the pixel seeds read inside and the arithmetic in uint32, whose
loop LLVM vectorises (about 5x the int64 loop on 32k paths, 0.14 against 0.72 ms).  Its two
kernels stay two calls: joined in one (or called from one), the vectorised loop ran 3x slower
whenever numba loaded it from its cache (numba 0.60; freshly compiled it did not).  Both give NumPy's
points bit for bit (tests/sampling/test_sobol_jit.py).  Imported only through engine/core/backend.py's
choice."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from .qmc import _DIM_SALT, _KEY_SALTS, _dim_hash

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

M32 = 0xFFFFFFFF
SALT0, SALT1, SALT2 = (int(s) for s in _KEY_SALTS)
TO_UNIT = 1.0 / 4294967296.0
DIM_SALT = int(_DIM_SALT)


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
    w = (1 << bits) - 1
    i = index ^ key
    i = (i * 0xE170893D) & M32
    i ^= key >> 16
    i ^= (i & w) >> 4
    i ^= key >> 8
    i = (i * 0x0929EB3F) & M32
    i ^= key >> 23
    i ^= (i & w) >> 1
    i = (i * (1 | (key >> 27))) & M32
    i = (i * 0x6935FA69) & M32
    i ^= (i & w) >> 11
    i = (i * 0x74DCB303) & M32
    i ^= (i & w) >> 2
    i = (i * 0x9E501CC3) & M32
    i ^= (i & w) >> 2
    i = (i * 0xC860A3DF) & M32
    i &= w
    i ^= i >> 5
    return (i + key) & w


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
def _u32(x):
    return np.uint32(x)


@jit
def _hash32_u32(x):
    """_hash32 in uint32 lanes (products wrap modulo 2^32 as NumPy's), which LLVM vectorises."""
    x = _u32(x ^ _u32(x >> _u32(16)))
    x = _u32(x * _u32(0x7FEB352D))
    x = _u32(x ^ _u32(x >> _u32(15)))
    x = _u32(x * _u32(0x846CA68B))
    return _u32(x ^ _u32(x >> _u32(16)))


@jit
def _reverse_bits_u32(x):
    x = _u32(_u32(_u32(x >> _u32(1)) & _u32(0x55555555)) | _u32(_u32(x & _u32(0x55555555)) << _u32(1)))
    x = _u32(_u32(_u32(x >> _u32(2)) & _u32(0x33333333)) | _u32(_u32(x & _u32(0x33333333)) << _u32(2)))
    x = _u32(_u32(_u32(x >> _u32(4)) & _u32(0x0F0F0F0F)) | _u32(_u32(x & _u32(0x0F0F0F0F)) << _u32(4)))
    x = _u32(_u32(_u32(x >> _u32(8)) & _u32(0x00FF00FF)) | _u32(_u32(x & _u32(0x00FF00FF)) << _u32(8)))
    return _u32(_u32(x >> _u32(16)) | _u32(x << _u32(16)))


@jit
def _dim1_reversed_u32(w):
    w = _u32(w ^ _u32(_u32(w >> _u32(1)) & _u32(0x55555555)))
    w = _u32(w ^ _u32(_u32(w >> _u32(2)) & _u32(0x33333333)))
    w = _u32(w ^ _u32(_u32(w >> _u32(4)) & _u32(0x0F0F0F0F)))
    w = _u32(w ^ _u32(_u32(w >> _u32(8)) & _u32(0x00FF00FF)))
    return _u32(w ^ _u32(w >> _u32(16)))


@jit
def _laine_karras_u32(x, seed):
    x = _u32(x + seed)
    x = _u32(x ^ _u32(x * _u32(0x6C50B47C)))
    x = _u32(x ^ _u32(x * _u32(0xB82F1E52)))
    x = _u32(x ^ _u32(x * _u32(0xC7AFE638)))
    return _u32(x ^ _u32(x * _u32(0x8D22F6E6)))


@jit
def _permute_u32(index, w, key):
    """qmc.permute: with bits = 0 the mask w = 0 gives its zeros."""
    i = _u32(index ^ key)
    i = _u32(i * _u32(0xE170893D))
    i = _u32(i ^ _u32(key >> _u32(16)))
    i = _u32(i ^ _u32(_u32(i & w) >> _u32(4)))
    i = _u32(i ^ _u32(key >> _u32(8)))
    i = _u32(i * _u32(0x0929EB3F))
    i = _u32(i ^ _u32(key >> _u32(23)))
    i = _u32(i ^ _u32(_u32(i & w) >> _u32(1)))
    i = _u32(i * _u32(_u32(1) | _u32(key >> _u32(27))))
    i = _u32(i * _u32(0x6935FA69))
    i = _u32(i ^ _u32(_u32(i & w) >> _u32(11)))
    i = _u32(i * _u32(0x74DCB303))
    i = _u32(i ^ _u32(_u32(i & w) >> _u32(2)))
    i = _u32(i * _u32(0x9E501CC3))
    i = _u32(i ^ _u32(_u32(i & w) >> _u32(2)))
    i = _u32(i * _u32(0xC860A3DF))
    i = _u32(i & w)
    i = _u32(i ^ _u32(i >> _u32(5)))
    return _u32(_u32(i + key) & w)


@jit
def _seeds(index, pixel, seed_table, dim):
    """(each path's pixel seed xor its dimension's hash, its index) as uint32; the dimension's hash
    is computed (qmc._dim_hash's table holds the same values)."""
    n = index.shape[0]
    seeds = np.empty(n, np.uint32)
    idx = np.empty(n, np.uint32)
    dim_salt = _u32(DIM_SALT)
    if n == 0:                  # (dim may be empty too: nothing to read)
        return seeds, idx
    if dim.shape[0] > 1:
        for k in range(n):
            seeds[k] = _u32(seed_table[pixel[k]] ^ _hash32_u32(_u32(_u32(dim[k]) + dim_salt)))
    else:
        dim_hash = _hash32_u32(_u32(_u32(dim[0]) + dim_salt))
        for k in range(n):
            seeds[k] = _u32(seed_table[pixel[k]] ^ dim_hash)
    for k in range(n):
        idx[k] = _u32(index[k])
    return seeds, idx


@jit
def _points(seeds, idx, mask):
    """The points of (pixel seed xor dimension hash, index) pairs, in uint32 arithmetic on contiguous
    arrays only: a loop LLVM vectorises (a kernel of its own: see the module's docstring)."""
    n = seeds.shape[0]
    x_out = np.empty(n, np.float64)
    y_out = np.empty(n, np.float64)
    salt0, salt1, salt2 = _u32(SALT0), _u32(SALT1), _u32(SALT2)
    for k in range(n):
        seed = _hash32_u32(seeds[k])
        i = _permute_u32(idx[k], mask, _hash32_u32(_u32(salt0 ^ seed)))
        x_out[k] = np.float64(_reverse_bits_u32(_laine_karras_u32(i, _hash32_u32(_u32(salt1 ^ seed))))) * TO_UNIT
        y_out[k] = np.float64(_reverse_bits_u32(_laine_karras_u32(_dim1_reversed_u32(i),
                                                                  _hash32_u32(_u32(salt2 ^ seed))))) * TO_UNIT
    return x_out, y_out


def _int64(a):
    a = np.asarray(a)
    return a if a.dtype == np.int64 and a.flags.c_contiguous else np.ascontiguousarray(a, np.int64)


_MASKS = {}     # count -> the mask of qmc.permute's bits, as uint32


def sample_2d_seeded(index, pixel, seed_table, dim, count: int = 1 << 16):
    """sample_2d(index, seed_table.take(pixel), dim, count) without the gather: each path's pixel seed
    and dimension hash are read inside the loop (qmc.SobolSampler.pair's compiled form)."""
    mask = _MASKS.get(count)
    if mask is None:
        bits = max(int(count - 1).bit_length(), 0)
        mask = _MASKS[count] = np.uint32((1 << bits) - 1)
    dim = _int64(dim)
    seeds, idx = _seeds(_int64(index).reshape(-1), _int64(pixel).reshape(-1), seed_table,
                        dim if dim.ndim == 1 else dim.reshape(-1))
    return _points(seeds, idx, mask)


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
