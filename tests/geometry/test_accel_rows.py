"""The accelerators' queries on rows (engine/geometry/accel/rows.py RowQueries): brute force and the
octree answer nearest_rows / occluded_rows from intersect() / occluded() on (N, 3) copies, the same
hits as Embree's own rows queries (kind, prim, occlusion; t within float32), and only Embree takes
the compiled loop (`compiled_rows`)."""
import numpy as np

from engine.core.vec import aos
from engine.geometry.accel import BruteForceAccelerator, EmbreeAccelerator, OctreeAccelerator
from engine.geometry.accel.rows import RowQueries


def scene(rng, k=100):
    centres = rng.uniform(-2, 2, (k, 1, 3))
    return centres + rng.normal(0, 0.3, (k, 3, 3))


def test_rows_queries_of_every_accelerator():
    rng = np.random.default_rng(4)
    tris = scene(rng)
    n = 1200
    o = rng.uniform(-3, 3, (3, n))
    d = rng.normal(size=(3, n))
    d /= np.linalg.norm(d, axis=0)
    bound = np.where(rng.random(n) < 0.3, 1.0, np.inf)
    answers = {}
    for cls in (BruteForceAccelerator, OctreeAccelerator, EmbreeAccelerator):
        accel = cls(tris)
        assert isinstance(accel, RowQueries)
        assert accel.compiled_rows == (cls is EmbreeAccelerator)
        t, kind, prim, u, v = accel.nearest_rows(o, d, bound.copy())
        assert kind.dtype == np.int8 and prim.dtype == np.int64
        tt, tp, _, _ = accel.intersect(aos(o, accel.ray_dtype), aos(d, accel.ray_dtype), bound)
        closer = tt < bound
        assert np.array_equal(kind, closer.astype(np.int8)) and np.array_equal(prim, np.where(closer, tp, -1))
        assert np.array_equal(t, np.where(closer, tt, bound))
        blocked = accel.occluded_rows(o, d, np.full(n, 1.5))
        answers[cls.__name__] = (kind, prim, t, blocked)
    brute, octree, embree = answers.values()
    assert brute[0].sum() > 50 and brute[3].sum() > 50
    for other in (octree, embree):
        same_hit = (brute[0] == other[0]).mean()
        assert same_hit > 0.99 and (brute[3] == other[3]).mean() > 0.99
        both = (brute[0] == 1) & (other[0] == 1) & (brute[1] == other[1])
        assert np.isclose(brute[2][both], other[2][both], rtol=1e-5).mean() > 0.99
    # Control: the bounds count (rays bounded at 1 lose their hits beyond it).
    accel = BruteForceAccelerator(tris)
    assert accel.nearest_rows(o, d, np.full(n, np.inf))[1].sum() > brute[0].sum()
