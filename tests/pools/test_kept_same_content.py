"""engine/pools/kept.py same_content: whether a frame's scene only moved the view is decided by
comparing arrays without array_equal's NaN masks; the answers must be array_equal's with NaN equal
to NaN (a wrong answer either renders a stale scene or prepares the scene again for nothing)."""
import numpy as np

from engine.pools.kept import same_content


def test_same_content_of_arrays_is_array_equal_with_nan_equal_to_nan():
    rng = np.random.default_rng(5)
    base = rng.normal(size=(50, 3))
    base[7, 1] = np.nan
    cases = []
    for where in [(0, 0), (25, 2), (49, 2), (7, 1)]:
        other = base.copy()
        other[where] = np.nan if where != (7, 1) else 1.0
        cases.append(other)
    negated = base.copy()
    negated[3, 0] = 0.0
    cases += [base.copy(), base + 1e-12, negated, base.astype(np.float32), base[:49]]
    zero = base.copy()
    zero[3, 0] = -0.0
    cases.append(zero)
    for other in cases:
        for a, b in ((base, other), (negated, other), (other, base)):
            expected = a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)
            assert same_content(a, b) == expected
    assert same_content(np.arange(4), np.arange(4)) and not same_content(np.arange(4), np.arange(1, 5))
    assert same_content(np.array(np.nan), np.full((), np.nan)) and not same_content(np.array(1.0), np.array(np.nan))
    # the control: NaN is not equal to NaN for ==, which same_content must not follow
    assert not np.array_equal(base, base.copy()) and same_content(base, base.copy())
