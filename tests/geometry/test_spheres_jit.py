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
