"""Octree and brute force agree with each other and with Embree (docs/hard-cases.md H6, H13, H14)."""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.geometry.accel import ACCELERATOR_CLASSES, choose_accelerator
from engine.geometry.accel.brute import BruteForceAccelerator
from engine.geometry.accel.embree import EmbreeAccelerator
from engine.geometry.accel.octree import OctreeAccelerator
from engine.scene.builtin import cornell_scene, torus
from engine.geometry.scene_geometry import SceneGeometry

from tests.scenes import diffuse_box_scene


def cornell_triangles():
    return SceneGeometry(cornell_scene()).triangles


def random_rays(n, seed=0):
    rng = np.random.default_rng(seed)
    o = rng.uniform(-0.95, 0.95, (n, 3)) + [0, 0, 1]
    d = rng.normal(size=(n, 3))
    d[: n // 10, 0] = -0.0                      # axis-aligned components, negative zero
    d[n // 10: n // 5, 1] = 0.0
    d /= np.linalg.norm(d, axis=1)[:, None]
    return o, d


@pytest.mark.slow          # 2-5 s (renders, subprocesses): make test-slow, which .ci/run runs too
def test_octree_matches_brute_force_exactly():
    tri = cornell_triangles()
    o, d = random_rays(3000)
    tb, pb, ub, vb = BruteForceAccelerator(tri).intersect(o, d, np.full(len(o), np.inf))
    to, po, uo, vo = OctreeAccelerator(tri).intersect(o, d, np.full(len(o), np.inf))
    assert np.array_equal(po, pb)
    assert np.allclose(to[pb >= 0], tb[pb >= 0], rtol=1e-12)
    assert (pb >= 0).mean() > 0.8


def test_embree_matches_brute_force():
    tri = cornell_triangles()
    o, d = random_rays(3000, seed=1)
    tb, pb, _, _ = BruteForceAccelerator(tri).intersect(o, d, np.full(len(o), np.inf))
    te, pe, _, _ = EmbreeAccelerator(tri).intersect(o, d, np.full(len(o), np.inf))
    assert (pe != pb).sum() <= 3          # float32 ties at shared edges
    same = pe == pb
    assert np.allclose(te[same & (pb >= 0)], tb[same & (pb >= 0)], rtol=1e-5)


def test_axis_aligned_rays_through_node_boundaries_and_room_walls():
    tri = cornell_triangles()
    oct_ = OctreeAccelerator(tri)
    # Origins exactly on the octree's mid-planes and on the wall planes x = +-1, directions along axes.
    g = np.linspace(-0.75, 0.75, 7)
    o = np.array([[x, y, 1.0] for x in g for y in g] + [[0.0, 0.0, 1.0], [-1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [-0.0, -0.0, 1.0]], float)
    O = np.repeat(o, len(dirs), axis=0)
    D = np.tile(dirs, (len(o), 1))
    tb, pb, _, _ = BruteForceAccelerator(tri).intersect(O, D, np.full(len(O), np.inf))
    to, po, _, _ = oct_.intersect(O, D, np.full(len(O), np.inf))
    assert np.array_equal(po, pb)


def test_octree_respects_tmax_and_occlusion():
    tri = cornell_triangles()
    o = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    d = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0]])
    occ = OctreeAccelerator(tri).occluded(o, d, np.array([0.5, 1.5]))
    assert occ.tolist() == [False, True]


def test_coincident_triangles_build_terminates_and_degenerates_never_hit():
    one = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)
    bad = np.array([[[-1113.45459, -79.049614, -56.2431908], [-1113.45459, -87.0922699, -56.2431908],
                     [-1113.45459, -79.2090149, -56.2431908]]])
    tri = np.concatenate([np.repeat(one, 200, axis=0), bad])
    acc = OctreeAccelerator(tri)
    assert acc.depth <= 10
    o = np.array([[0.2, 0.2, 1.0], [-1081.47925, 99.9999542, 87.7701111]])
    d = np.array([[0, 0, -1.0], [-32.1072998, -183.355865, -144.607635]])
    d /= np.linalg.norm(d, axis=1)[:, None]
    t, p, _, _ = acc.intersect(o, d, np.full(2, np.inf))
    assert p[0] >= 0 and t[0] == pytest.approx(1.0)
    assert p[1] == -1 and np.isinf(t[1])          # pbrt's Triangle.BadCases: no hit, no NaN


def test_octree_and_embree_images_agree_pixel_by_pixel():
    scene = diffuse_box_scene(resolution=(12, 12))
    scene.meshes.append(torus("Torus", (0, 0.4, 0.3), 0.25, 0.1, 12, 8, 0))
    a = render(scene, RenderSettings(samples=4, accelerator="embree", seed=5), log=lambda *x: None)
    b = render(scene, RenderSettings(samples=4, accelerator="octree", seed=5), log=lambda *x: None)
    diff = np.abs(a.image - b.image)
    assert np.median(diff) < 1e-5
    assert (diff < 1e-3 * (1 + np.abs(a.image))).mean() > 0.95
    assert a.stats["accelerator"] == "embree" and b.stats["accelerator"] == "octree"


def test_auto_choice_is_explained():
    name, reason = choose_accelerator("auto", 5000)
    assert name == "embree" and "auto" in reason
    assert set(ACCELERATOR_CLASSES) == {"embree", "octree", "brute"}
