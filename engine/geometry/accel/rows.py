"""The accelerators' queries on rays given as (3, N) float64 rows (engine/core/vec.py), which
SceneGeometry asks: by default through intersect() and occluded() on (N, 3) copies of the
accelerator's ray_dtype.  Embree overrides them (engine/geometry/accel/embree.py: given the compiled
loop of embree_jit.py it calls Embree on the rows themselves, `compiled_rows`)."""
from __future__ import annotations

import numpy as np

from ...core.vec import aos


class RowQueries:
    compiled_rows = False       # True: nearest_rows / occluded_rows take embree_jit's compiled loop

    def nearest_rows(self, o, d, t, compiled=None):
        """(t, kind, prim, u, v): the triangle hits nearer than the bounds t (N,) lower them (a new
        array), kind 1 (TRIANGLE) there else 0, prim the triangle there else -1; u, v of intersect()."""
        tt, tp, u, v = self.intersect(aos(o, self.ray_dtype), aos(d, self.ray_dtype), t)
        closer = tt < t
        return np.where(closer, tt, t), closer.astype(np.int8), np.where(closer, tp, -1), u, v

    def occluded_rows(self, o, d, tmax, compiled=None):
        """occluded() of the rays as rows."""
        return self.occluded(aos(o, self.ray_dtype), aos(d, self.ray_dtype), tmax)
