"""The index shuffle (engine/sampling/qmc.py permute) and what the renderer asks of it: a bijection
of [0, 2^bits) for every key and bit count, so a pixel's samples take distinct points of its net for
every sample count (non-powers of two, light nets of samples x shadow rays, any unit or pass of
them); and pixels whose errors are independent (no image-space structure).  Each check has a
control that a broken shuffle or seeding fails."""
import numpy as np
import pytest

from engine.sampling import qmc
from engine.sampling.qmc import permute, pixel_seeds, sample_2d

KEYS = np.random.default_rng(26).integers(0, 2 ** 32, 48, dtype=np.uint64).astype(np.uint32)


def bijective_bits(perm, bits_range=range(0, 13)):
    """The bit counts for which perm(., bits, key) is not a bijection of [0, 2^bits) for some key."""
    bad = []
    for bits in bits_range:
        n = 1 << bits
        index = np.tile(np.arange(n, dtype=np.uint32), len(KEYS))
        out = perm(index, bits, np.repeat(KEYS, n)).astype(np.int64).reshape(len(KEYS), n)
        if not (np.sort(out, axis=1) == np.arange(n)).all():
            bad.append(bits)
    return bad


def test_the_shuffle_is_a_bijection_for_every_bit_count():
    assert bijective_bits(permute) == []


def test_the_bijection_check_catches_a_shuffle_that_is_not_one():
    """Control: Kensler's shuffle with its last xorshift replaced by an or-shift (two indices of 16
    and more points can meet) and a shuffle that drops the top index bit."""
    def or_shift(index, bits, key):
        w = np.uint32((1 << bits) - 1)
        x = permute(index, bits, key)
        return (x | (x >> np.uint32(3))) & w
    assert bijective_bits(or_shift) != []
    assert bijective_bits(lambda i, bits, key: permute(i & np.uint32((1 << max(bits - 1, 0)) - 1), bits, key),
                          range(1, 6)) == [1, 2, 3, 4, 5]


def repeated_counts(counts):
    """The sample counts among `counts` whose samples do not take distinct points of a pixel's net
    for a dimension pair (x is the scrambled bit-reversed index: distinct x, distinct shuffled
    indices), or reach 1."""
    seeds = pixel_seeds(9, np.arange(2), np.zeros(2))
    bad = []
    for count in counts:
        for seed in seeds:
            x, y = sample_2d(np.arange(count), np.full(count, seed, np.uint32), 5, count)
            if len(np.unique(x)) != count or max(x.max(), y.max()) >= 1.0:
                bad.append(count)
                break
    return bad


@pytest.mark.parametrize("counts", [range(1, 257), (300, 768, 1000, 1023, 1025, 3000, 4095, 4096)])
def test_every_sample_count_takes_distinct_points(counts):
    """Sample counts of renders: any, not only powers of two, and the light nets of samples x shadow
    rays."""
    assert repeated_counts(counts) == []


def test_distinct_points_catch_a_shuffle_that_drops_a_bit(monkeypatch):
    """Control: the shuffle of the index without its top bit (two samples on one point)."""
    monkeypatch.setattr(qmc, "permute", lambda i, bits, key: permute(i >> np.uint32(1), bits, key))
    assert repeated_counts((2, 3, 100, 1000)) == [2, 3, 100, 1000]


def test_passes_of_a_pixel_take_the_points_of_the_whole():
    """Units, halves and progressive passes trace sample numbers [start, stop): the points of a pass
    are those of the same numbers in the whole render (the net does not depend on the split)."""
    seed = np.uint32(pixel_seeds(2, np.array([4]), np.array([7]))[0])
    whole = sample_2d(np.arange(96), np.full(96, seed), 3, 96)
    for start, stop in ((0, 1), (1, 2), (2, 4), (4, 8), (8, 16), (16, 96), (37, 61)):
        part = sample_2d(np.arange(start, stop), np.full(stop - start, seed), 3, 96)
        assert np.array_equal(part[0], whole[0][start:stop]) and np.array_equal(part[1], whole[1][start:stop])


def pixel_error_autocorrelation(seed_of=None, n=16, size=128):
    """The largest |autocorrelation| at lags 1-4 px (along x and y) of the per-pixel errors of n-point
    estimates of a smooth integrand of two dimension pairs (one pair's coordinates times the other's,
    as a camera jitter pair and a light pair of the same samples), over a size x size image."""
    yy, xx = np.mgrid[0:size, 0:size]
    seeds = (pixel_seeds(11, xx.ravel(), yy.ravel()) if seed_of is None else seed_of(xx.ravel(), yy.ravel()))
    seeds = np.repeat(seeds, n)
    index = np.tile(np.arange(n), size * size)
    a, b = sample_2d(index, seeds, 0, n), sample_2d(index, seeds, 6, n)
    f = np.sin(3 * a[0]) * a[1] + b[0] * b[1] + a[0] * b[1]
    err = f.reshape(size, size, n).mean(axis=2)
    err = (err - err.mean()) / err.std()
    r = [abs(float((err[:, lag:] * err[:, :-lag]).mean())) for lag in range(1, 5)]
    r += [abs(float((err[lag:] * err[:-lag]).mean())) for lag in range(1, 5)]
    return max(r)


def test_pixel_errors_are_spatially_independent():
    """No image-space structure: |r| at lags 1-4 px within 4 standard errors (1 / sqrt(pixels))."""
    assert pixel_error_autocorrelation() < 4 / 128


def test_the_autocorrelation_catches_pixels_that_share_a_seed():
    """Control: pairs of neighbouring pixels with the same seed (the seed of x // 2)."""
    assert pixel_error_autocorrelation(lambda x, y: pixel_seeds(11, x // 2, y)) > 4 / 128
