"""np.searchsorted(a[:n], key, side="right") for the compiled twins that pick from a cumulative table
(engine/lights/environment_jit.py, engine/lights/selection_jit.py, engine/materials/mix_jit.py): one
binary search with NumPy's order, a NaN after every number (a NaN key counts every value; a NaN value
is above every number), so each twin's index is NumPy's (their tests compare them on NaN inputs too).
Imported only by those modules, which engine/core/backend.py imports."""
from __future__ import annotations

from ..core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def search_right(a, n, key):
    """The first index i < n whose a[i] is above key in NumPy's order (n when there is none)."""
    lo, hi = 0, n
    while lo < hi:
        mid = (lo + hi) >> 1
        v = a[mid]
        if key < v or (v != v and key == key):
            hi = mid
        else:
            lo = mid + 1
    return lo
