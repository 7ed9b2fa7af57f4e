"""The compiled quad test (engine/geometry/shapes/quads_jit.py) against the NumPy one
(engine/geometry/shapes/quads.py) on inputs recorded from a render of the built-in Cornell box
(its lamp is a quad), and on quads sharing an edge, rays along the diagonal and parallel rays
(docs/hard-cases.md H8)."""
import numpy as np

from engine.geometry.shapes.quads import QuadSet
from tests.backend_capture import capture, require_compiled

TWIN = "engine.geometry.shapes.quads_jit"      # imported by QuadSet(backend="numba"): numba may be missing


def both(corners):
    return QuadSet(corners), QuadSet(corners, backend="numba")


def test_captured_tests_are_bit_identical():
    require_compiled()
    calls = capture("cornell")["quad"]
    assert len(calls) > 5
    for quads, k, prim, o, d, t_best in calls:
        compiled = QuadSet(np.stack([quads.v00, quads.v10, quads.v11, quads.v01], axis=1), backend="numba")
        if prim is None:
            assert np.array_equal(quads.intersect_one(k, o, d, t_best), compiled.intersect_one(k, o, d, t_best))
        else:
            assert np.array_equal(quads.intersect_pairs(prim, o, d, t_best), compiled.intersect_pairs(prim, o, d, t_best))


def test_shared_edges_diagonals_and_pairs():
    require_compiled()
    rng = np.random.default_rng(8)
    # Two quads sharing the edge x = 0 in z = 1, a skewed one, and one seen edge-on.
    corners = np.array([[[-1, -1, 1], [0, -1, 1], [0, 1, 1], [-1, 1, 1]],
                        [[0, -1, 1], [1, -1, 1], [1, 1, 1], [0, 1, 1]],
                        [[-1, -1, 2], [1, -0.5, 2.2], [1.2, 1, 2.4], [-0.7, 0.8, 2.1]],
                        [[-1, 0, 0], [1, 0, 0], [1, 0, 3], [-1, 0, 3]]], float)
    numpy_quads, compiled = both(corners)
    m = 20000
    o = np.zeros((3, m))
    target = np.stack([rng.uniform(-1.3, 1.3, m), rng.uniform(-1.3, 1.3, m), np.ones(m)])
    target[0, :2000] = 0.0                                     # on the shared edge
    target[:2, 2000:4000] = rng.uniform(-1, 1, 2000) * np.array([[1.0], [-1.0]])   # the diagonal of quad 0/1
    d = target - o
    d /= np.linalg.norm(d, axis=0)
    d[:, 4000:4100] = [[1.0], [0.0], [0.0]]                     # parallel to the planes z = 1
    bound = np.where(rng.random(m) < 0.3, 1.2, np.inf)
    hits = 0
    for k in range(len(corners)):
        for t_best in (None, bound):
            a, b = numpy_quads.intersect_one(k, o, d, t_best), compiled.intersect_one(k, o, d, t_best)
            assert np.array_equal(a, b)
            hits += np.isfinite(a).sum()
    assert hits > 10000
    prim = rng.integers(0, len(corners), m)
    assert np.array_equal(numpy_quads.intersect_pairs(prim, o, d, bound), compiled.intersect_pairs(prim, o, d, bound))
    # Control: the comparison sees a quad moved off its plane by 1e-12.
    moved = QuadSet(corners + np.array([0.0, 0.0, 1e-12]), backend="numba")
    assert not np.array_equal(numpy_quads.intersect_one(0, o, d, None), moved.intersect_one(0, o, d, None))


def test_all_quads_in_one_loop_fold_as_scene_geometry():
    """nearest_quads and occluded_by_quads (every quad against each ray in one loop) against
    SceneGeometry's NumPy fold over the quads: the same t, kind and prim (of equal distances the lowest
    number: the shared edge), and the same blocked rays; a control with the quads' order reversed."""
    require_compiled()
    from engine.geometry import scene_geometry
    from engine.geometry.scene_geometry import QUAD
    from engine.geometry.shapes import quads_jit
    rng = np.random.default_rng(11)
    corners = np.array([[[-1, -1, 1], [0, -1, 1], [0, 1, 1], [-1, 1, 1]],
                        [[0, -1, 1], [1, -1, 1], [1, 1, 1], [0, 1, 1]],
                        [[-1, -1, 2], [1, -0.5, 2.2], [1.2, 1, 2.4], [-0.7, 0.8, 2.1]],
                        [[0.2, -0.5, 0.5], [0.8, -0.5, 0.5], [0.8, 0.5, 0.5], [0.2, 0.5, 0.5]]], float)
    numpy_quads, compiled = both(corners)
    m = 20000
    o = np.zeros((3, m))
    d = np.stack([rng.uniform(-1.3, 1.3, m), rng.uniform(-1.3, 1.3, m), np.ones(m)])
    d[0, :2000] = 0.0                                           # on the shared edge: a tie
    d /= np.linalg.norm(d, axis=0)
    d[:, 2000] = np.nan
    t0 = np.where(rng.random(m) < 0.3, rng.uniform(0.4, 3.0, m), np.inf)
    kind0 = np.where(np.isfinite(t0), 1, 0).astype(np.int8)
    prim0 = np.where(np.isfinite(t0), 7, -1).astype(np.int64)
    geometry = object.__new__(scene_geometry.SceneGeometry)

    def fold(quads, order=slice(None)):
        geometry.quads = quads
        kind, prim = kind0.copy(), prim0.copy()
        t = scene_geometry.SceneGeometry._nearest(QUAD, None, quads.count, geometry._quad_test(o, d), o, d,
                                                  t0.copy(), kind, prim)
        return t, kind, prim
    reference = fold(numpy_quads)
    kind, prim = kind0.copy(), prim0.copy()
    t = quads_jit.nearest_quads(compiled, o, d, t0, kind, prim, QUAD)
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(reference, (t, kind, prim)))
    assert (kind == QUAD).sum() > 5000 and (prim[:2000] == 0).any() and (prim[:2000] == 1).sum() == 0
    hit = rng.random(m) < 0.1
    tmax = np.where(rng.random(m) < 0.5, 1.05, 10.0)
    expected = hit.copy()
    for k in range(len(corners)):
        expected |= numpy_quads.intersect_one(k, o, d, tmax) < tmax
    quads_jit.occluded_by_quads(compiled, o, d, tmax, hit)
    assert np.array_equal(hit, expected) and expected.sum() > 5000
    # Control: quads 0 and 1 in the other order give the shared edge's rays the other quad, which is seen.
    flipped = fold(QuadSet(corners[[1, 0, 2, 3]]))
    assert not np.array_equal(np.where(flipped[2] == 0, 1, np.where(flipped[2] == 1, 0, flipped[2])), prim)
