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

Everything is vectorised over uint32 arrays; bit reversal and the Sobol' generator matrix of
the second dimension go through byte tables.
"""
from __future__ import annotations

import numpy as np

U32 = np.uint32
_REV8 = np.array([int(f"{i:08b}"[::-1], 2) for i in range(256)], dtype=np.uint32)


def _sobol_dim1_tables():
    """Byte tables T[j][b] = XOR of the direction numbers of bits set in byte j of the index."""
    v = [1 << 31]
    for _ in range(31):
        v.append(v[-1] ^ (v[-1] >> 1))
    tables = np.zeros((4, 256), dtype=np.uint32)
    for j in range(4):
        for b in range(256):
            acc = 0
            for t in range(8):
                if b >> t & 1:
                    acc ^= v[8 * j + t]
            tables[j, b] = acc
    return tables


_SOBOL1 = _sobol_dim1_tables()


def reverse_bits(x: np.ndarray) -> np.ndarray:
    x = x.astype(np.uint32, copy=False)
    return ((_REV8[x & U32(255)] << U32(24)) | (_REV8[(x >> U32(8)) & U32(255)] << U32(16))
            | (_REV8[(x >> U32(16)) & U32(255)] << U32(8)) | _REV8[x >> U32(24)])


def sobol_dim1(i: np.ndarray) -> np.ndarray:
    return (_SOBOL1[0][i & U32(255)] ^ _SOBOL1[1][(i >> U32(8)) & U32(255)]
            ^ _SOBOL1[2][(i >> U32(16)) & U32(255)] ^ _SOBOL1[3][i >> U32(24)])


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
    """A keyed pseudo-random permutation of [0, 2^bits) (rounds of xor with a key, multiply by
    an odd constant and xorshift, all modulo 2^bits).  Unlike an Owen scramble of the index,
    it keeps no bit of the index in place, so pairs of dimensions shuffled with different
    keys are independent of each other."""
    if bits == 0:
        return np.zeros_like(index)
    mask = U32((1 << bits) - 1)
    shift = U32(max(1, (bits + 1) // 2))
    x = index & mask
    for odd, rotate in ((0x2C1B3C6D, 0), (0x297A2D39, 11), (0x9E3779B9, 22)):
        x = (x ^ (key >> U32(rotate))) & mask
        x = (x * U32(odd)) & mask
        x ^= x >> shift
    return x


def sample_2d(index: np.ndarray, pixel_seed: np.ndarray, dim, count: int = 1 << 16
              ) -> tuple[np.ndarray, np.ndarray]:
    """Point `index` (< count) of the scrambled 2D Sobol' net of (pixel, dimension pair `dim`),
    as two float64 arrays in [0, 1).  `dim` is an int or an array like `index`.  The index is
    first permuted within [0, 2^ceil(log2 count)), with a key of its own per (pixel, dim)."""
    bits = max(int(count - 1).bit_length(), 0)
    with np.errstate(over="ignore"):
        seed = hash32(pixel_seed ^ hash32(np.asarray(dim, dtype=np.uint32) + U32(0x68E31DA4)))
        # Three independent keys: the shuffle and each coordinate's scramble.  (Keys that are
        # odd multiples of one seed share its low bit, and the low bits of the Laine-Karras keys
        # decide the top bits of x and y: the pair's two numbers would fall in the same half.)
        i = permute(np.asarray(index, dtype=np.uint32), bits, hash32(seed ^ U32(0x1B873593)))
        # Dimension 0 is the bit-reversed index: its Owen scramble needs one reversal only.
        x = reverse_bits(laine_karras(i, hash32(seed ^ U32(0xA511E9B3))))
        y = owen_scramble(sobol_dim1(i), hash32(seed ^ U32(0x63D83595)))
    scale = 1.0 / 4294967296.0
    one = np.nextafter(1.0, 0.0)
    return np.minimum(x * scale, one), np.minimum(y * scale, one)


class SobolSampler:
    """The uniforms of one tile's paths: pair(pixel, index, dim) -> two arrays in [0, 1).

    pixel: tile-local pixel of each path (its seed comes from the pixel's place in the
    frame), index: the sample's number within its pixel (times the shadow-ray count plus
    the ray's number, for light samples), dim: the dimension pair (engine/integrators/path_tracer.py)."""
    name = "sobol"

    def __init__(self, seed: int, x0: int, y0: int, x1: int, y1: int, samples: int, shadow_rays: int):
        tile_width = x1 - x0
        pixel = np.arange(tile_width * (y1 - y0))
        self.pixel_seed = pixel_seeds(seed, x0 + pixel % tile_width, y0 + pixel // tile_width)
        self.count = samples
        self.light_count = samples * max(shadow_rays, 1)

    def pair(self, pixel, index, dim, light=False):
        """light: the index runs over the shadow rays of all samples (a larger net)."""
        return sample_2d(index, self.pixel_seed.take(pixel), dim, self.light_count if light else self.count)


class RandomSampler:
    """Independent uniforms from one generator per tile (the report's plain Monte Carlo)."""
    name = "random"

    def __init__(self, rng):
        self.rng = rng

    def pair(self, pixel, index, dim, light=False):
        n = len(pixel)
        return self.rng.random(n), self.rng.random(n)
