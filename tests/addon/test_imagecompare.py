"""The comparison's runs are independent (tests/addon/imagecompare.py): TNCG15 MC's seeds s and s + 1
give the same camera samples one pixel row apart (engine/sampling/qmc.py pixel_seeds), so runs at
consecutive seeds are correlated and their spread understates the noise of their mean; the runs
take `independent_seed` instead.  And the comparison's statistics on synthetic runs: its block
z-scores have unit spread for independent runs and too large a spread for correlated ones (the control)."""
import numpy as np
import pytest

from imagecompare import SEED_STRIDE, compare_runs, independent_seed
from engine.sampling.qmc import pixel_seeds

ROWS, COLS = 256, 64


def seeds_of(seed):
    y, x = np.mgrid[0:ROWS, 0:COLS]
    return pixel_seeds(seed, x.ravel(), y.ravel()).reshape(ROWS, COLS)


def test_consecutive_seeds_share_camera_samples_one_row_apart():
    """The control: what independent_seed avoids (if the sampler changes, independent_seed may go)."""
    a, b = seeds_of(1000), seeds_of(1001)
    assert np.array_equal(b[:-1], a[1:])


@pytest.mark.parametrize("first, second", [(1000, 1001), (1000, 1003), (1000, 3000), (2, 32767)])
def test_independent_seeds_share_no_pixel_seed(first, second):
    a, b = seeds_of(independent_seed(first)), seeds_of(independent_seed(second))
    assert not np.isin(a, b).any()


def test_independent_seed_keeps_within_the_seed_limits():
    assert independent_seed(0) == 0 and independent_seed(1) == SEED_STRIDE
    assert independent_seed((1 << 15) - 1) < 1 << 31
    with pytest.raises(ValueError):
        independent_seed(1 << 15)


def runs(rng, k, shared=0.0, shape=(64, 64, 3)):
    """K runs of a flat image, pixel noise 0.1; `shared`: the share of the noise's variance that the K
    runs have in common (correlated runs, as at consecutive seeds)."""
    common = rng.normal(0.0, 0.1, shape)
    own = rng.normal(0.0, 0.1, (k,) + shape)
    return 0.5 + np.sqrt(shared) * common + np.sqrt(1.0 - shared) * own


def z_spread(shared, trials=6):
    rng = np.random.default_rng(7)
    z = []
    for _ in range(trials):
        r = compare_runs(runs(rng, 4, shared), runs(rng, 4, shared), tau=0.0)
        z.append((r.details["block_delta"] / r.details["block_se"]).ravel())
    return float(np.concatenate(z).std())


def test_block_z_has_unit_spread_for_independent_runs_and_not_for_correlated_ones():
    assert 0.9 < z_spread(0.0) < 1.1
    assert z_spread(0.5) > 1.3           # runs sharing half their noise: the comparison is fooled
