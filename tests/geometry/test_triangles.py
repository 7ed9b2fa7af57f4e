"""engine/geometry/accel/triangles.py: the vectorised Möller-Trumbore test against one ray at a time
in plain Python, and its edge cases (degenerate triangles, parallel rays, nothing to test)."""
import numpy as np

from engine.geometry.accel.triangles import TriangleArrays, moller_trumbore


def one_ray(tri, o, d):
    """The textbook test for one ray and one triangle: t or None."""
    e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
    p = np.cross(d, e2)
    det = e1 @ p
    if det == 0:
        return None
    s = o - tri[0]
    u = s @ p / det
    q = np.cross(s, e1)
    v = d @ q / det
    t = e2 @ q / det
    return (t, u, v) if u >= 0 and v >= 0 and u + v <= 1 and t > 0 else None


def test_nearest_hits_match_the_one_ray_reference():
    rng = np.random.default_rng(6)
    triangles = rng.uniform(-1, 1, (30, 3, 3))
    tris = TriangleArrays(triangles)
    o = rng.uniform(-2, 2, (300, 3))
    d = rng.normal(scale=0.3, size=(300, 3)) - o                  # roughly towards the triangles
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    subset = np.arange(3, 30, 2)
    t, which, u, v = moller_trumbore(tris, subset, o, d)
    hits = 0
    for r in range(300):
        found = [(one_ray(triangles[k], o[r], d[r]), k) for k in subset]
        found = [(h, k) for h, k in found if h is not None]
        if not found:
            assert np.isinf(t[r]) and which[r] == -1 and u[r] == v[r] == 0
            continue
        (t_ref, u_ref, v_ref), k = min(found, key=lambda f: f[0][0])
        hits += 1
        assert which[r] == k
        np.testing.assert_allclose([t[r], u[r], v[r]], [t_ref, u_ref, v_ref], rtol=1e-9, atol=1e-12)
    assert 30 < hits < 270


def test_degenerate_triangles_parallel_rays_and_empty_inputs_give_no_hit_and_no_nan():
    triangles = np.array([[[0, 0, 0], [1, 0, 0], [2, 0, 0]],           # a line: det = 0
                          [[0, 0, 0], [0, 0, 0], [0, 0, 0]],           # a point
                          [[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)  # a real one, in z = 0
    tris = TriangleArrays(triangles)
    o = np.array([[0.2, 0.2, 1], [0.5, 0, 1], [-1, 0.2, 0], [0.2, 0.2, 1]], float)
    d = np.array([[0, 0, -1], [0, 0, -1], [1, 0, 0], [0, 0, 1]], float)
    t, which, u, v = moller_trumbore(tris, np.arange(3), o, d)
    assert t[0] == 1.0 and which[0] == 2
    assert np.isinf(t[2]) and which[2] == -1                     # in the triangle's plane
    assert np.isinf(t[3])                                         # pointing away
    assert not np.isnan(np.r_[t, u, v]).any()
    t, which, _, _ = moller_trumbore(tris, np.arange(2), o, d)   # only the degenerate ones
    assert np.isinf(t).all() and (which == -1).all()
    t, which, u, v = moller_trumbore(tris, np.array([], np.int64), o, d)
    assert np.isinf(t).all() and (which == -1).all() and t.shape == (4,)
    assert moller_trumbore(tris, np.arange(3), np.zeros((0, 3)), np.zeros((0, 3)))[0].shape == (0,)
