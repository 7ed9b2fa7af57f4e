"""Intersection routines against analytic answers, grazing and parallel rays included."""
import numpy as np
import pytest

from engine.geometry.accel.embree import EmbreeAccelerator
from engine.geometry.scene_geometry import NONE, QUAD, SPHERE, TRIANGLE, Counters, SceneGeometry
from engine.scene.model import Camera, Material, Quad, Scene, Sphere, TriangleMesh
from engine.geometry.shapes.quads import QuadSet
from engine.geometry.shapes.spheres import intersect_sphere, surface_point
from engine.core.vec import rows


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class TestSphere:
    def test_head_on_hit_and_miss(self):
        o = np.array([[0, 0, -5.0], [0, 2, -5.0], [0, 0, 5.0]])
        d = np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, 1.0]])
        t = intersect_sphere(rows(o), rows(d), np.zeros(3), 1.0)
        assert t[0] == pytest.approx(4.0, abs=1e-12)
        assert np.isinf(t[1]) and np.isinf(t[2])  # passes beside; sphere behind

    def test_from_inside_hits_far_side(self):
        t = intersect_sphere(rows([[0.0, 0, 0]]), rows([[1.0, 0, 0]]), np.zeros(3), 2.0)
        assert t[0] == pytest.approx(2.0, abs=1e-12)

    def test_chord_length_matches_analytic(self):
        rng = np.random.default_rng(1)
        offsets = rng.uniform(-0.99, 0.99, 200)
        o = np.stack([offsets, np.zeros(200), np.full(200, -10.0)], axis=1)
        d = np.tile([0, 0, 1.0], (200, 1))
        t = intersect_sphere(rows(o), rows(d), np.zeros(3), 1.0)
        assert np.allclose(t, 10.0 - np.sqrt(1 - offsets ** 2), rtol=1e-12)

    def test_grazing_tangent_rays(self):
        # Rays at 0.999 r hit, at 1.001 r miss, for a tiny sphere far away (docs/hard-cases.md H9).
        c = np.array([0.0, 0.0, 1e4])
        r = 1e-3
        n = 1000
        phi = np.random.default_rng(2).uniform(0, 2 * np.pi, n)
        for scale, expect_hit in ((0.999, True), (1.001, False)):
            target = c + scale * r * np.stack([np.cos(phi), np.sin(phi), np.zeros(n)], axis=1)
            d = unit(target)
            t = intersect_sphere(np.zeros((3, n)), rows(d), c, r)
            assert (np.isfinite(t) == expect_hit).all()
            if expect_hit:
                p, normal, _ = surface_point(np.zeros((3, n)), rows(d), t, rows(np.tile(c, (n, 1))), np.full(n, r))
                assert np.abs(np.linalg.norm(p.T - c, axis=1) - r).max() <= 1e-12 * np.abs(c).max()
                raw = d * t[:, None]
                assert np.abs(np.linalg.norm(raw - c, axis=1) - r).max() <= 1e-6 * r

    def test_degenerate_direction_is_a_miss_not_nan(self):
        t = intersect_sphere(rows([[0, 0, -5.0]]), rows([[0, 0, 0.0]]), np.zeros(3), 1.0)
        assert np.isinf(t[0])


class TestQuad:
    corners = np.array([[[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]], dtype=float)

    def test_center_diagonal_and_corners_hit(self):
        qs = QuadSet(self.corners)
        pts = np.array([[1, 0.5, 0], [1.0, 0.5, 0], [0.5, 0.75, 0], [1e-9, 1e-9, 0], [2 - 1e-9, 1 - 1e-9, 0]])
        # Points on the internal diagonal (0,1)-(2,0): parametrised exactly.
        s = np.linspace(0.001, 0.999, 50)
        diag = np.stack([2 * s, 1 - s, np.zeros_like(s)], axis=1)
        pts = np.concatenate([pts, diag])
        o = pts + np.array([0, 0, 3.0])
        d = np.tile([0, 0, -1.0], (len(o), 1))
        t = qs.intersect_one(0, rows(o), rows(d))
        assert np.allclose(t, 3.0, rtol=1e-12)

    def test_outside_misses(self):
        qs = QuadSet(self.corners)
        o = np.array([[2.01, 0.5, 1], [-0.01, 0.5, 1], [1, 1.01, 1], [1, -0.01, 1]])
        t = qs.intersect_one(0, rows(o), rows(np.tile([0, 0, -1.0], (4, 1))))
        assert np.isinf(t).all()

    def test_parallel_in_plane_ray_is_a_miss(self):
        qs = QuadSet(self.corners)
        o = np.array([[-1, 0.5, 0.0], [-1, 0.5, 1e-12]])
        t = qs.intersect_one(0, rows(o), rows(np.tile([1.0, 0, 0], (2, 1))))
        assert np.isinf(t).all()

    def test_general_convex_quad_matches_two_triangles(self):
        q = np.array([[[0, 0, 0], [3, 0, 0], [2.5, 2, 0], [0.2, 1.5, 0]]], dtype=float)
        qs = QuadSet(q)
        rng = np.random.default_rng(3)
        xy = rng.uniform(-0.5, 3.5, (4000, 2))
        o = np.concatenate([xy, np.ones((4000, 1))], axis=1)
        t = qs.intersect_one(0, rows(o), rows(np.tile([0, 0, -1.0], (4000, 1))))

        def inside_tri(p, a, b, c):
            def s(p1, p2, p3):
                return (p1[:, 0] - p3[0]) * (p2[1] - p3[1]) - (p2[0] - p3[0]) * (p1[:, 1] - p3[1])
            d1, d2, d3 = s(p, a, b), s(p, b, c), s(p, c, a)
            return ~(((d1 < 0) | (d2 < 0) | (d3 < 0)) & ((d1 > 0) | (d2 > 0) | (d3 > 0)))
        v = q[0, :, :2]
        expected = inside_tri(xy, v[0], v[1], v[2]) | inside_tri(xy, v[0], v[2], v[3])
        assert (np.isfinite(t) == expected).all()


class TestEmbree:
    def test_hit_distance_and_barycentrics(self):
        tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], dtype=float)
        acc = EmbreeAccelerator(tri)
        o = np.array([[0.2, 0.3, 2.0], [2, 2, 2.0]])
        d = np.array([[0, 0, -1.0], [0, 0, -1.0]])
        t, prim, u, v = acc.intersect(o, d, np.full(2, np.inf))
        assert t[0] == pytest.approx(2.0, rel=1e-6) and prim[0] == 0
        assert u[0] == pytest.approx(0.2, abs=1e-6) and v[0] == pytest.approx(0.3, abs=1e-6)
        assert np.isinf(t[1]) and prim[1] == -1

    def test_occluded_respects_tmax(self):
        tri = np.array([[[-1, -1, 0], [1, -1, 0], [0, 1, 0]]], dtype=float)
        acc = EmbreeAccelerator(tri)
        o = np.tile([0, 0, 1.0], (2, 1))
        d = np.tile([0, 0, -1.0], (2, 1))
        assert acc.occluded(o, d, np.array([0.5, 1.5])).tolist() == [False, True]

    def test_robust_shared_edge(self):
        # Mitsuba's test10_embree_robust_flag (docs/hard-cases.md H4): rays through a shared edge.
        v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
        tri = v[np.array([[0, 1, 2], [0, 2, 3]])]
        acc = EmbreeAccelerator(tri)
        rng = np.random.default_rng(4)
        s = rng.uniform(0.01, 0.99, 1024)
        target = np.stack([s, s, np.zeros_like(s)], axis=1)
        o = target + unit(rng.normal(size=(1024, 3)) * [1, 1, 0] + [0, 0, 2.0])
        t, prim, _, _ = acc.intersect(o, unit(target - o), np.full(1024, np.inf))
        assert (prim >= 0).all()


def _mixed_scene():
    mats = [Material("m")]
    tri = TriangleMesh("T", np.array([[-5, -5, 3], [5, -5, 3], [0, 5, 3]], float), np.array([[0, 1, 2]]), [0])
    quad = Quad("Q", np.array([[-5, -5, 2], [5, -5, 2], [5, 5, 2], [-5, 5, 2]], float), 0)
    sph = Sphere("S", (0, 0, 1), 0.5, 0)
    return Scene(Camera.look_at((0, 0, 10), (0, 0, 0), up=(0, 1, 0)), mats, [tri], [sph], [quad])


def test_nearest_hit_across_kinds():
    geo = SceneGeometry(_mixed_scene())
    o = np.array([[0, 0, 0.0], [0, 0, 1.8], [0, 0, 2.5], [0, 0, 4.0], [9, 9, 0.0]])
    d = np.tile([0, 0, 1.0], (5, 1))
    t, kind, prim, u, v = geo.intersect(rows(o), rows(d), Counters())
    assert kind.tolist() == [SPHERE, QUAD, TRIANGLE, NONE, NONE]
    assert t[:3] == pytest.approx([0.5, 0.2, 0.5], rel=1e-6)
    assert np.isinf(t[3:]).all()


def test_nan_ray_never_wins_the_nearest_hit():
    geo = SceneGeometry(_mixed_scene())
    o = np.array([[0, 0, 0.0], [np.nan, 0, 0.0]])
    d = np.array([[0, 0, 1.0], [0, 0, 1.0]])
    t, kind, prim, u, v = geo.intersect(rows(o), rows(d), Counters())
    assert kind[0] == SPHERE and t[0] == pytest.approx(0.5)
    assert kind[1] == NONE and np.isinf(t[1])
