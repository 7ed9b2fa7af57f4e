"""engine/film/accumulator.py: per-pixel sums, squares and counts, the pixel mean and the variance of
that mean, against NumPy on the same samples."""
import numpy as np

from engine.film.accumulator import Film


def test_sums_mean_and_variance_of_the_mean_match_numpy():
    rng = np.random.default_rng(2)
    width, height = 5, 3
    film = Film(width, height)
    pixel = rng.integers(0, width * height - 1, 4000)            # the last pixel gets no sample
    radiance = rng.gamma(2.0, 1.0, (3, 4000))
    for part in np.array_split(np.arange(4000), 7):                # added in chunks, as the tracer does
        film.add_samples(pixel[part], radiance[:, part])
    mean, var = film.mean(), film.variance_of_mean()
    assert mean.shape == var.shape == (height, width, 3)
    for p in range(width * height - 1):
        values = radiance[:, pixel == p].T
        y, x = divmod(p, width)
        assert film.count[y, x] == len(values)
        np.testing.assert_allclose(film.sum[y, x], values.sum(axis=0), rtol=1e-12)
        np.testing.assert_allclose(film.sum_sq[y, x], (values ** 2).sum(axis=0), rtol=1e-12)
        np.testing.assert_allclose(mean[y, x], values.mean(axis=0), rtol=1e-6)
        np.testing.assert_allclose(var[y, x], values.var(axis=0, ddof=1) / len(values), rtol=1e-5)
    assert film.count[-1, -1] == 0 and (mean[-1, -1] == 0).all() and (var[-1, -1] == 0).all()


def test_one_sample_has_no_negative_or_nan_variance():
    film = Film(2, 1)
    film.add_samples(np.array([0]), np.array([[1.0], [2.0], [3.0]]))
    assert np.isfinite(film.variance_of_mean()).all() and (film.variance_of_mean() >= 0).all()
    assert film.mean()[0, 0].tolist() == [1.0, 2.0, 3.0]


def _every_pixel_both_ways(width, height, radiance, add=Film.add_every_pixel):
    """(film after add_every_pixel, film after add_samples of the same sample-major samples), both
    with earlier sums in them."""
    n = width * height
    mine, before = Film(width, height), Film(width, height)
    for film in (mine, before):
        film.add_samples(np.arange(n), np.full((3, n), 0.25))
    add(mine, radiance)
    before.add_samples(np.tile(np.arange(n), radiance.shape[1] // max(n, 1)), radiance)
    return mine, before


def _hard_samples(samples, n, seed=5):
    """Samples whose sums depend on their order (magnitudes 1e-12 .. 1e16), with -0.0, inf and NaN."""
    rng = np.random.default_rng(seed)
    radiance = rng.standard_normal((3, samples * n)) * 10.0 ** rng.integers(-12, 17, (3, samples * n))
    radiance[0, :n] = -0.0
    if samples * n > 7:
        radiance[1, 3], radiance[2, 5], radiance[2, 7] = np.inf, np.nan, -np.inf
    return radiance


def test_every_pixel_sums_are_add_samples_bit_for_bit():
    """engine/film/ordered_samples.py's flush of a full unit: the reduction over the samples gives
    bincount's sums exactly, on order-sensitive samples, one pixel, one sample and none."""
    for width, height, samples in ((96, 96, 16), (7, 3, 40), (2, 1, 1000), (1, 1, 300), (5, 4, 1), (3, 3, 0)):
        radiance = _hard_samples(samples, width * height)
        mine, before = _every_pixel_both_ways(width, height, radiance)
        for a, b in ((mine.sum, before.sum), (mine.sum_sq, before.sum_sq), (mine.count, before.count)):
            assert a.tobytes() == b.tobytes(), (width, height, samples)


def test_control_a_pairwise_sum_of_the_samples_is_caught():
    """Control: summing each pixel's samples pairwise (NumPy's sum along a contiguous axis: the
    pixel-major order) changes last bits, which the comparison above would catch."""
    def pairwise(film, radiance):
        n = film.width * film.height
        rows = np.ascontiguousarray(radiance.reshape(3, -1, n).transpose(0, 2, 1))     # (3, n, S)
        film.count.reshape(n)[:] += rows.shape[2]
        film.sum.reshape(n, 3)[:] += rows.sum(axis=2).T
        film.sum_sq.reshape(n, 3)[:] += (rows * rows).sum(axis=2).T
    mine, before = _every_pixel_both_ways(7, 3, _hard_samples(40, 21), add=pairwise)
    assert mine.sum.tobytes() != before.sum.tobytes()
