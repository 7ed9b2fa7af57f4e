"""Quasi-Monte Carlo sample points: Owen-scrambled, shuffled 2D Sobol' points (Burley,
"Practical Hash-based Owen Scrambling", JCGT 9(4), 2020), as Cycles' and pbrt-v4's default
samplers use.

Sample i of a pixel takes, for each pair of dimensions d (camera jitter, light sample, BSDF
sample ... at each bounce), the i-th point of a 2D Sobol' sequence whose index order is
shuffled and whose points are Owen-scrambled with seeds hashed from (render seed, pixel, d).
The spp points of a pixel are then a scrambled (0, m, 2)-net in every pair (stratified in
every elementary interval), each pair independently randomised: unbiased like independent
uniforms, with much lower variance for the smooth parts of an integrand (direct light,
area lights, pixel footprints).  Random numbers depend only on (seed, pixel, sample index,
dimension), never on tiles, threads or the order paths are traced in.

Everything is vectorised over uint32 arrays in shifts, masks and xors (no table gathers): bit
reversal swaps ever larger bit groups and then the bytes; the second dimension's Sobol' matrix
(Pascal's triangle modulo 2) is a superset-parity transform of the index bits.
"""
from __future__ import annotations

import numpy as np

U32 = np.uint32
# (shift, mask) of the bit-group swaps of reverse_bits, and of the superset xors of sobol_dim1
_SWAPS = tuple((U32(1 << k), U32(m)) for k, m in enumerate((0x55555555, 0x33333333, 0x0F0F0F0F)))
_SUPERSETS = tuple((U32(1 << k), U32(m)) for k, m in enumerate((0x55555555, 0x33333333, 0x0F0F0F0F,
                                                                 0x00FF00FF, 0x0000FFFF)))


def reverse_bits(x: np.ndarray) -> np.ndarray:
    """Bit 31 - k of each result is bit k of x (a new uint32 array)."""
    x = np.array(x, dtype=np.uint32)
    for shift, mask in _SWAPS:         # swap neighbouring bits, pairs, nibbles: each byte reversed
        low = x & mask
        x >>= shift
        x &= mask
        low <<= shift
        x |= low
    return x.byteswap(inplace=True)    # then the byte order


def sobol_dim1_reversed(i: np.ndarray) -> np.ndarray:
    """The second Sobol' dimension of index i, bit-reversed (bit j of the result is bit 31 - j of
    sobol_dim1(i)).  Its direction numbers v_k = v_(k-1) xor (v_(k-1) >> 1), v_0 = 1 << 31, are the
    columns of Pascal's triangle modulo 2: bit 31 - j of v_k is binomial(k, j) mod 2, which is 1
    exactly when the bits of j are a subset of those of k (Lucas' theorem).  So bit j of the
    reversed point is the parity of the bits k of i with k a superset of j: five xor-shifts."""
    w = np.array(i, dtype=np.uint32)
    for shift, mask in _SUPERSETS:     # bit j ^= bit j + shift, for the j without that bit
        t = w >> shift
        t &= mask
        w ^= t
    return w


def sobol_dim1(i: np.ndarray) -> np.ndarray:
    """The second dimension of the Sobol' sequence at index i (32-bit fixed point)."""
    return reverse_bits(sobol_dim1_reversed(i))


def hash32(x: np.ndarray) -> np.ndarray:
    """A well-mixed 32-bit hash (Wellons' lowbias32)."""
    x = np.array(x, dtype=np.uint32)
    x ^= x >> U32(16)
    x *= U32(0x7FEB352D)
    x ^= x >> U32(15)
    x *= U32(0x846CA68B)
    x ^= x >> U32(16)
    return x


def laine_karras(x: np.ndarray, seed: np.ndarray) -> np.ndarray:
    """Laine and Karras' hash: a random permutation that flips each bit depending on the
    bits below it only (Owen scrambling when applied to bit-reversed values)."""
    x = x + seed
    x ^= x * U32(0x6C50B47C)
    x ^= x * U32(0xB82F1E52)
    x ^= x * U32(0xC7AFE638)
    x ^= x * U32(0x8D22F6E6)
    return x


def owen_scramble(x: np.ndarray, seed: np.ndarray) -> np.ndarray:
    return reverse_bits(laine_karras(reverse_bits(x), seed))


def pixel_seeds(seed: int, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """One 32-bit seed per pixel (x, y) of a render with `seed`."""
    with np.errstate(over="ignore"):
        key = (np.asarray(x, dtype=np.uint32) * U32(0x9E3779B1)) ^ hash32(np.asarray(y, dtype=np.uint32)
                                                                            + U32(seed & 0xFFFFFFFF))
    return hash32(key ^ U32((seed >> 32) & 0xFFFFFFFF))


def permute(index: np.ndarray, bits: int, key: np.ndarray) -> np.ndarray:
    """A keyed pseudo-random permutation of [0, 2^bits): Kensler's hash permutation ("Correlated
    Multi-Jittered Sampling", Pixar Technical Memo 13-01, 2013, its permute() for a power-of-two
    length, where no cycle walking is needed): xors with the key, odd multiplies and xorshifts of
    the masked bits, then a rotation by the key.  Pairs of dimensions shuffled with different keys
    are independent as if each pair's order were drawn at random: the 4D cells of two pairs' points
    fill as those of random orders at 16, 64 and 256 points, and the components' contingency
    tables at 4096 pass (tests/sampling/test_qmc.py).  Neither did on their own: the three
    xor-multiply-xorshift rounds used before kept the pairs' coarse strata correlated (4D chi^2 8x
    that of random orders at 64 points; 1.4-1.8x Cycles' direct-light variance at glossy
    highlights, docs/performance.md), and Burley's nested (Owen) scramble of the index keeps the
    finer strata of the pairs related (the contingency tables fail)."""
    if bits == 0:
        return np.zeros_like(index)
    w = U32((1 << bits) - 1)
    p = np.asarray(key, dtype=np.uint32)
    i = np.array(index, dtype=np.uint32)
    with np.errstate(over="ignore"):
        i ^= p
        i *= U32(0xE170893D)
        i ^= p >> U32(16)
        i ^= (i & w) >> U32(4)
        i ^= p >> U32(8)
        i *= U32(0x0929EB3F)
        i ^= p >> U32(23)
        i ^= (i & w) >> U32(1)
        i *= U32(1) | (p >> U32(27))
        i *= U32(0x6935FA69)
        i ^= (i & w) >> U32(11)
        i *= U32(0x74DCB303)
        i ^= (i & w) >> U32(2)
        i *= U32(0x9E501CC3)
        i ^= (i & w) >> U32(2)
        i *= U32(0xC860A3DF)
        i &= w
        i ^= i >> U32(5)
        return (i + p) & w


# Salts of the three keys of a (pixel, dim) seed: the index shuffle and the scrambles of x and y.
_KEY_SALTS = np.array([0x1B873593, 0xA511E9B3, 0x63D83595], dtype=np.uint32)
_DIM_SALT = U32(0x68E31DA4)
_DIM_HASHES = hash32(np.arange(1024, dtype=np.uint32) + _DIM_SALT)      # hash32(dim + salt) of small dims


def _dim_hash(dim) -> np.ndarray:
    """hash32(dim + _DIM_SALT), read from a table for arrays of dims below 1024 (every render's)."""
    dim = np.asarray(dim)
    if dim.ndim and dim.size and dim.dtype.kind in "iu" and dim.min() >= 0 and dim.max() < len(_DIM_HASHES):
        return _DIM_HASHES.take(dim)
    return hash32(dim.astype(np.uint32) + _DIM_SALT)


def sample_2d(index: np.ndarray, pixel_seed: np.ndarray, dim, count: int = 1 << 16
              ) -> tuple[np.ndarray, np.ndarray]:
    """Point `index` (< count) of the scrambled 2D Sobol' net of (pixel, dimension pair `dim`),
    as two float64 arrays in [0, 1).  `dim` is an int or an array like `index`.  The index is
    first permuted within [0, 2^ceil(log2 count)), with a key of its own per (pixel, dim)."""
    bits = max(int(count - 1).bit_length(), 0)
    index = np.asarray(index, dtype=np.uint32)
    with np.errstate(over="ignore"):
        seed = hash32(pixel_seed ^ _dim_hash(dim))
        if seed.shape != index.shape:
            seed = np.broadcast_to(seed, np.broadcast_shapes(seed.shape, index.shape))
        # Three independent keys: the shuffle and each coordinate's scramble.  (Keys that are
        # odd multiples of one seed share its low bit, and the low bits of the Laine-Karras keys
        # decide the top bits of x and y: the pair's two numbers would fall in the same half.)
        keys = hash32(np.bitwise_xor.outer(_KEY_SALTS, seed))
        i = permute(index, bits, keys[0])
        # Dimension 0 is the bit-reversed index, dimension 1 sobol_dim1: the Owen scramble
        # reverse_bits(laine_karras(reverse_bits(point))) of each needs one reversal only.  Both
        # coordinates go through the hash and the reversal together, as the rows of one array.
        pair = np.stack((i, sobol_dim1_reversed(i)))
        xy = reverse_bits(laine_karras(pair, keys[1:])) * (1.0 / 4294967296.0)
    # (2^32 - 1) / 2^32 is exact in float64 and below 1: every coordinate is in [0, 1)
    return xy[0], xy[1]


class SobolSampler:
    """The uniforms of one tile's paths: pair(pixel, index, dim) -> two arrays in [0, 1).

    pixel: tile-local pixel of each path (its seed comes from the pixel's place in the
    frame), index: the sample's number within its pixel (times the shadow-ray count plus
    the ray's number, for light samples), dim: the dimension pair (engine/integrators/path_tracer.py)."""
    name = "sobol"
    kernel = staticmethod(sample_2d)   # or its numba twin engine/sampling/sobol_jit.py (engine/rendering/session.py)
    # With numba: sobol_jit.sample_2d_seeded, which reads each path's pixel seed itself (no gather).
    seeded_kernel = None

    def __init__(self, seed: int, x0: int, y0: int, x1: int, y1: int, samples: int, shadow_rays: int):
        tile_width = x1 - x0
        pixel = np.arange(tile_width * (y1 - y0))
        self.pixel_seed = pixel_seeds(seed, x0 + pixel % tile_width, y0 + pixel // tile_width)
        self.count = samples
        self.light_count = samples * max(shadow_rays, 1)

    def pair(self, pixel, index, dim, light=False):
        """light: the index runs over the shadow rays of all samples (a larger net)."""
        count = self.light_count if light else self.count
        if self.seeded_kernel is not None:
            return self.seeded_kernel(index, pixel, self.pixel_seed, dim, count)
        return self.kernel(index, self.pixel_seed.take(pixel), dim, count)


class RandomSampler:
    """Independent uniforms from one generator per tile (the report's plain Monte Carlo)."""
    name = "random"

    def __init__(self, rng):
        self.rng = rng

    def pair(self, pixel, index, dim, light=False):
        n = len(pixel)
        return self.rng.random(n), self.rng.random(n)
