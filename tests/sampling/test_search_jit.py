"""engine/sampling/search_jit.py's search_right against np.searchsorted(a[:n], key, side="right") on
sorted tables with ties, with NaNs at their end (NumPy's order: a NaN after every number) and with NaN,
infinite and out-of-range keys, over prefixes n.  Control: the comparison search without NumPy's NaN
order (what mix_jit and selection_jit had) is told apart on a table ending in NaNs."""
import importlib

import numpy as np
import pytest

from tests.backend_capture import require_compiled


def twin():
    require_compiled()
    return importlib.import_module("engine.sampling.search_jit")


def tables(rng):
    yield np.array([0.0])
    yield np.zeros(5)                                              # all ties
    yield np.cumsum(rng.integers(0, 3, 40).astype(np.float64))      # ties and steps
    a = np.cumsum(rng.random(30))
    yield np.concatenate([a, [np.nan] * 4])                           # a cumsum after a NaN probability
    yield np.array([-np.inf, -1.0, 0.0, 0.0, 2.5, np.inf])


def keys(a):
    finite = a[np.isfinite(a)]
    base = [np.nan, np.inf, -np.inf, -1e300, 1e300, 0.0]
    base += list(finite) + list(np.nextafter(finite, np.inf)) + list(np.nextafter(finite, -np.inf))
    return np.array(base, dtype=np.float64)


def test_search_right_is_numpys_searchsorted_right():
    search = twin().search_right
    rng = np.random.default_rng(5)
    checked = 0
    for a in tables(rng):
        for n in sorted({0, 1, len(a) // 2, len(a)}):
            for key in keys(a):
                assert search(a, n, key) == np.searchsorted(a[:n], key, side="right"), (a[:n], key)
                checked += 1
    assert checked > 500


def test_control_a_search_without_numpys_nan_order_differs():
    def plain(a, n, key):                         # the loop mix_jit and selection_jit had
        lo, hi = 0, n
        while lo < hi:
            mid = (lo + hi) >> 1
            if key < a[mid]:
                hi = mid
            else:
                lo = mid + 1
        return lo
    search = twin().search_right
    a = np.array([0.25, 0.5, np.nan, np.nan, np.nan])              # its first probe is a NaN
    assert np.searchsorted(a, 0.3, side="right") == search(a, len(a), 0.3) == 1
    assert plain(a, len(a), 0.3) == 5                               # walks past the NaNs
    finite = np.cumsum(np.full(8, 0.25))                            # without NaNs the two agree
    assert all(plain(finite, 8, k) == search(finite, 8, k) for k in keys(finite))
