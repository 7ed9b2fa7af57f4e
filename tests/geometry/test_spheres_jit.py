"""The compiled sphere test (engine/geometry/shapes/spheres_jit.py) against the NumPy one
(engine/geometry/shapes/spheres.py `intersect_sphere`, picked by `sphere_kernel`) on inputs
recorded from a render of the built-in Cornell box, and on the hard cases of docs/hard-cases.md
H9-H10 (a tiny sphere far away, rays grazing it, origins inside)."""
import numpy as np

from engine.geometry.shapes.spheres import intersect_sphere, sphere_kernel
from tests.backend_capture import capture, require_compiled

TWIN = "engine.geometry.shapes.spheres_jit"        # imported by sphere_kernel("numba"), not here: numba may be missing


def test_captured_tests_are_bit_identical():
    require_compiled()
    compiled = sphere_kernel("numba")
    calls = capture("cornell")["sphere"]
    assert len(calls) > 10 and any(c[4] is not None for c in calls)
    for o, d, center, radius, t_best in calls:
        assert np.array_equal(intersect_sphere(o, d, center, radius, t_best),
                              compiled(o, d, center, radius, t_best))


def test_hard_cases_and_pairs():
    require_compiled()
    compiled = sphere_kernel("numba")
    rng = np.random.default_rng(3)
    m = 5000
    center, radius = np.array([1e4, 0.0, 0.0]), 1e-3
    target = center[:, None] + rng.normal(size=(3, m)) * 1.2e-3       # grazing: hits and misses
    o = np.zeros((3, m))
    o[:, :100] = center[:, None]                                      # from inside
    d = target - o
    d /= np.linalg.norm(d, axis=0)
    d[:, :100] = rng.normal(size=(3, 100))
    d[:, :100] /= np.linalg.norm(d[:, :100], axis=0)
    t = intersect_sphere(o, d, center, radius)
    assert np.isfinite(t).sum() > 1000 and np.isinf(t).sum() > 1000
    assert np.array_equal(t, compiled(o, d, center, radius))
    bound = np.where(rng.random(m) < 0.5, np.inf, 1e4)
    assert np.array_equal(intersect_sphere(o, d, center, radius, bound), compiled(o, d, center, radius, bound))
    centers = rng.random((3, m)) * 2.0                                # one sphere per ray
    radii = rng.random(m) * 0.5
    o2, d2 = rng.random((3, m)), rng.normal(size=(3, m))
    d2 /= np.linalg.norm(d2, axis=0)
    assert np.array_equal(intersect_sphere(o2, d2, centers, radii, bound), compiled(o2, d2, centers, radii, bound))
    # Control: the comparison sees a sphere 1 ulp larger.
    assert not np.array_equal(t, compiled(o, d, center, np.nextafter(radius, 1.0)))


def test_all_spheres_in_one_loop_match_the_loop_over_spheres():
    """spheres_jit nearest_spheres / occluded_by_spheres against SceneGeometry's NumPy loop over the
    spheres (nearer replaces; equal distances keep the lower number; each test bounded by the t so far)."""
    require_compiled()
    from engine.geometry.shapes.spheres import sphere_loop_kernels
    nearest, occluded = sphere_loop_kernels("numba")
    assert sphere_loop_kernels("numpy") is None
    rng = np.random.default_rng(5)
    centers = rng.random((3, 12)) * 4.0
    centers[:, 11] = centers[:, 10]                                    # a duplicate: the lower number wins
    radii = rng.random(12) * 0.6 + 0.05
    radii[11] = radii[10]
    m = 6000
    o = rng.random((3, m)) * 4.0
    d = rng.normal(size=(3, m))
    d /= np.linalg.norm(d, axis=0)
    t0 = np.where(rng.random(m) < 0.3, rng.random(m) * 2.0, np.inf)    # some nearer triangle hits already
    t, kind, prim = t0.copy(), np.zeros(m, np.int8), np.full(m, -1, np.int64)
    for k in range(12):                                                # SceneGeometry._nearest's loop
        tk = intersect_sphere(o, d, centers[:, k], radii[k], t)
        closer = tk < t
        t = np.where(closer, tk, t)
        kind[closer], prim[closer] = 2, k
    kind_b, prim_b = np.zeros(m, np.int8), np.full(m, -1, np.int64)
    t_b = nearest(o, d, centers, radii, t0, kind_b, prim_b, 2)
    assert np.isfinite(t).sum() > 1000 and (prim == 10).any() and not (prim == 11).any()
    assert np.array_equal(t, t_b) and np.array_equal(kind, kind_b) and np.array_equal(prim, prim_b)
    tmax = rng.random(m) * 3.0
    hit = np.zeros(m, dtype=bool)
    for k in range(12):
        hit |= intersect_sphere(o, d, centers[:, k], radii[k], tmax) < tmax
    hit_b = np.zeros(m, dtype=bool)
    occluded(o, d, centers, radii, tmax, hit_b)
    assert 500 < hit.sum() < m - 500 and np.array_equal(hit, hit_b)
    # Control: one radius 1 ulp larger is told apart.
    bigger = radii.copy()
    bigger[3] = np.nextafter(bigger[3], 1.0)
    assert not np.array_equal(t, nearest(o, d, centers, bigger, t0, kind_b, prim_b, 2))


def test_one_loop_pretests_keep_grazing_and_inside_rays_and_reject_nan():
    """The loops' branch-free pre-tests (spheres_jit._candidates) on the hard cases of docs/hard-cases.md
    H9-H10: tiny spheres far away and rays grazing them, origins inside a sphere looking away from its
    centre (hits that only the pre-test's `c <= 0` lets through: counted, so a pre-test that dropped it
    fails), and NaN directions (never a hit)."""
    require_compiled()
    from engine.geometry.shapes.spheres import sphere_loop_kernels
    nearest, occluded = sphere_loop_kernels("numba")
    rng = np.random.default_rng(11)
    s, m = 6, 8000
    centers = np.array([1e4, 0.0, 0.0])[:, None] + rng.normal(size=(3, s)) * 3e-3
    radii = 1e-3 * (1.0 + rng.random(s))
    which = rng.integers(0, s, m)
    u = rng.normal(size=(3, m))
    u[0, : m // 2] = 0.0                                     # half of them at the silhouette, seen from 0
    u /= np.linalg.norm(u, axis=0)
    target = centers[:, which] + u * radii[which] * (1.0 + 1e-3 * rng.normal(size=m))
    o = np.zeros((3, m))
    o[:, -500:] = centers[:, which[-500:]] + 0.5 * radii[which[-500:]] * u[:, -500:]   # inside a sphere
    d = target - o
    d[:, -500:] = rng.normal(size=(3, 500))                  # in any direction
    d /= np.linalg.norm(d, axis=0)
    d[:, :50] = np.nan
    t, kind, prim = np.full(m, np.inf), np.zeros(m, np.int8), np.full(m, -1, np.int64)
    leaving = 0
    for k in range(s):
        tk = intersect_sphere(o, d, centers[:, k], radii[k], t)
        f = o - centers[:, k:k + 1]
        leaving += int((np.isfinite(tk) & ((f * d).sum(axis=0) > 0.0)).sum())
        closer = tk < t
        t = np.where(closer, tk, t)
        kind[closer], prim[closer] = 2, k
    kind_b, prim_b = np.zeros(m, np.int8), np.full(m, -1, np.int64)
    t_b = nearest(o, d, centers, radii, np.full(m, np.inf), kind_b, prim_b, 2)
    assert leaving > 100 and 1000 < np.isfinite(t).sum() < m - 1000 and np.isinf(t[:50]).all()
    assert np.array_equal(t, t_b) and np.array_equal(kind, kind_b) and np.array_equal(prim, prim_b)
    tmax = np.where(rng.random(m) < 0.5, 2e4, 9999.99)
    hit = np.zeros(m, dtype=bool)
    for k in range(s):
        hit |= intersect_sphere(o, d, centers[:, k], radii[k], tmax) < tmax
    hit_b = np.zeros(m, dtype=bool)
    occluded(o, d, centers, radii, tmax, hit_b)
    assert 500 < hit.sum() < m - 500 and np.array_equal(hit, hit_b)
