"""The pixel filter (engine/film/pixel_filter.py): the box of width 1 is the old jitter bit for bit;
the importance-sampled filters' sample positions follow the filter (χ², with a wrong-width control);
the table is Cycles' (symmetric about the pixel centre, inside the footprint)."""
import numpy as np
import pytest

from engine.core.settings import RenderSettings
from engine.film.pixel_filter import FOOTPRINT, PixelFilter, filter_function, filter_table, pixel_filter_for
from tests.chi_square import ALPHA, pooled_chi2

N = 200_000
BINS = 60


def bin_probabilities(f: PixelFilter, edges: np.ndarray, tabulated: bool) -> np.ndarray:
    """The probability of each bin (offsets from the pixel centre) under the filter: as its table
    samples it (the inverse CDF is piecewise linear: mass 1/1022 between neighbouring entries), or
    the analytic filter's (trapezoid rule on a fine grid)."""
    half = 0.5 * f.footprint
    if tabulated and f.table is not None:
        cdf = np.interp(edges, f.table - 0.5, np.linspace(0.0, 1.0, len(f.table)))
    else:
        x = np.linspace(-half, half, 200_001)
        y = np.abs(filter_function(f.kind, f.width)(x))
        c = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]))])
        cdf = np.interp(edges, x, c / c[-1], left=0.0, right=1.0)
    return np.diff(cdf)


def filter_chi2(sampled: PixelFilter, expected: PixelFilter, seed: int = 0) -> float:
    """p-value of `sampled`'s offsets against the density `expected`'s table samples."""
    u = np.random.default_rng(seed).random(N)
    half = 0.5 * max(sampled.footprint, expected.footprint)
    edges = np.linspace(-half, half, BINS + 1)
    observed = np.histogram(sampled.offsets(u) - 0.5, edges)[0]
    return pooled_chi2(observed, bin_probabilities(expected, edges, tabulated=True) * N)[0]


def table_error(table: PixelFilter, analytic: PixelFilter) -> float:
    """Total variation distance between a table's density and an analytic filter (60 bins)."""
    half = 0.5 * max(table.footprint, analytic.footprint)
    edges = np.linspace(-half, half, BINS + 1)
    return 0.5 * np.abs(bin_probabilities(table, edges, True) - bin_probabilities(analytic, edges, False)).sum()


def test_the_reference_box_is_the_plain_jitter():
    assert pixel_filter_for(RenderSettings()) is None           # no work at all: the camera samples as before
    u = np.random.default_rng(1).random(1000)
    assert np.array_equal(PixelFilter("box", 1.0).offsets(u), u)


@pytest.mark.parametrize("kind,width", [("box", 2.0), ("gaussian", 1.5), ("blackman-harris", 1.5),
                                        ("blackman-harris", 3.0)])
def test_samples_follow_the_filter(kind, width):
    assert filter_chi2(PixelFilter(kind, width), PixelFilter(kind, width), seed=1) > ALPHA


@pytest.mark.parametrize("kind", ["box", "gaussian", "blackman-harris"])
def test_control_a_wrong_width_fails(kind):
    assert filter_chi2(PixelFilter(kind, 1.5), PixelFilter(kind, 1.35), seed=1) < 1e-6


@pytest.mark.parametrize("kind", ["gaussian", "blackman-harris"])
def test_the_table_is_the_filter(kind):
    """Cycles' table is the filter up to its tabulation (piecewise linear in the inverse CDF: the
    far tails get their mass spread evenly): below 0.3 % of the samples move between bins; a table
    of the wrong width (the control) moves over 3 %."""
    assert table_error(PixelFilter(kind, 1.5), PixelFilter(kind, 1.5)) < 0.003
    assert table_error(PixelFilter(kind, 1.35), PixelFilter(kind, 1.5)) > 0.03


def test_table_is_symmetric_and_inside_the_footprint():
    for kind in ("gaussian", "blackman-harris"):
        t = filter_table(kind, 1.5)
        half = 0.5 * FOOTPRINT[kind] * 1.5
        assert len(t) == 1023 and abs(t[511] - 0.5) < 1e-6
        assert np.allclose(t + t[::-1], 1.0, atol=1e-12)
        assert np.all(np.diff(t) > 0)
        assert abs(t[0] - (0.5 - half)) < 1e-9 and abs(t[-1] - (0.5 + half)) < 1e-9


def test_bad_filters_are_refused():
    from engine.core.errors import SceneError
    with pytest.raises(SceneError, match="pixel filter"):
        PixelFilter("mitchell", 1.0)
    with pytest.raises(SceneError, match="width"):
        PixelFilter("gaussian", 0.0)
