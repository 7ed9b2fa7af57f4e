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
