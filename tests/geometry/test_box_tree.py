"""engine/geometry/shapes/box_tree.py: many spheres, quads and Area lights through the BoxTree give
exactly the hits of the one-primitive-after-the-other loop (engine/geometry/scene_geometry.py
LOOP_MAX), whose results are the analytic tests' own: nearest hit, its primitive (ties: the lowest
number), the shadow-ray answer, the seen-lamps radiance and a rendered image, compared with exact
array equality.  Controls: a tree that drops one leaf's pairs, and a merge that lets the highest
number win ties, are both caught by the same comparisons."""
import numpy as np
import pytest

from engine.api import render
from engine.core.settings import RenderSettings
from engine.core.vec import dot, rows
from engine.geometry import scene_geometry as sg
from engine.geometry.shapes import box_tree
from engine.geometry.shapes.box_tree import BoxTree, padded_boxes
from engine.geometry.shapes.spheres import intersect_sphere
from engine.lights.seen import SeenLamps
from engine.scene.model import (MIRROR, AreaLight, Camera, Material, PointLight, Quad, Scene, Sphere,
                                TriangleMesh)


LOOP = {kind: 10**9 for kind in sg.LOOP_MAX}      # LOOP_MAX for the loop alone, and for the tree
TREE = {kind: 8 for kind in sg.LOOP_MAX}


class Plan:
    enabled = {"triangles": True, "spheres": True, "quads": True, "area_lights": True, "smooth_normals": False}


def crowd(k=150, seed=3):
    """Overlapping spheres, quads and Area lights (3 to 8 corners, mixed visibility) over a floor."""
    rng = np.random.default_rng(seed)
    c, r = rng.uniform(-1, 1, (k, 3)), rng.uniform(0.02, 0.25, k)
    spheres = [Sphere(f"s{i}", tuple(c[i]), float(r[i]), 0) for i in range(k)]
    spheres += [Sphere("twin", tuple(c[0]), float(r[0]), 0)]            # coincident: the lower number wins
    qc, h = rng.uniform(-1, 1, (k, 3)), rng.uniform(0.02, 0.2, k)
    quads = [Quad(f"q{i}", np.array([qc[i] + (-h[i], -h[i], 0), qc[i] + (h[i], -h[i], 0), qc[i] + (h[i], h[i], 0),
                                     qc[i] + (-h[i], h[i], 0)]), 0) for i in range(k)]
    # Two coplanar quads sharing an edge (x = 0.0 at z = 1.5): rays along it are a tie.
    quads += [Quad("left", np.array([(-0.5, -0.5, 1.5), (0.0, -0.5, 1.5), (0.0, 0.5, 1.5), (-0.5, 0.5, 1.5)]), 0),
              Quad("right", np.array([(0.0, -0.5, 1.5), (0.5, -0.5, 1.5), (0.5, 0.5, 1.5), (0.0, 0.5, 1.5)]), 0)]
    lights = []
    for i in range(k):
        m = int(rng.integers(3, 9))
        a = 2 * np.pi * np.arange(m) / m
        v = qc[i] + np.stack([0.1 * np.cos(a), np.zeros(m), 0.1 * np.sin(a)], 1)[::-1] + (0.05, 0.1, 0.0)
        lights.append(AreaLight(f"l{i}", v, (1.0, 1.0, 1.0), visible_camera=bool(i % 2), visible_glossy=bool(i % 3)))
    floor = TriangleMesh("floor", np.array([(-2, -2, -0.5), (2, -2, -0.5), (2, 2, -0.5), (-2, 2, -0.5)], float),
                         np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]))
    return Scene(Camera.look_at((0, -3, 0), (0, 0, 0)), [Material("m")], [floor], spheres, quads, lights=lights), c, r


def rays(c, r, n=6000, seed=4):
    """Random rays, a quarter of them leaving sphere surfaces (as after a bounce), some along the
    coplanar quads' shared edge and some parallel to the axes (zero direction components)."""
    rng = np.random.default_rng(seed)
    o = rng.uniform(-1.5, 1.5, (n, 3))
    d = rng.normal(size=(n, 3))
    q = n // 4
    j = rng.integers(0, len(r), q)
    normal = rng.normal(size=(q, 3))
    o[:q] = c[j] + r[j][:, None] * normal / np.linalg.norm(normal, axis=1)[:, None]
    o[q:q + 50] = np.c_[np.zeros(50), rng.uniform(-0.4, 0.4, 50), np.full(50, 2.5)]    # onto the shared edge
    d[q:q + 50] = (0.0, 0.0, -1.0)
    d[q + 50:q + 150] = np.eye(3)[rng.integers(0, 3, 100)] * rng.choice([-1.0, 1.0], (100, 1))
    d /= np.linalg.norm(d, axis=1)[:, None]
    return rows(o), rows(d), rng.integers(0, 4, n).astype(np.int8), rng.uniform(0.05, 3.0, n)


def queries(scene, o, d, ray_kind, tmax, loop_max, monkeypatch):
    monkeypatch.setattr(sg, "LOOP_MAX", loop_max)
    g = sg.SceneGeometry(scene, plan=Plan())
    assert (g.sphere_tree is None) == (loop_max == LOOP)
    return g.intersect(o, d, sg.Counters(), ray_kind=ray_kind), g.occluded(o, d, tmax, sg.Counters())


@pytest.fixture(scope="module")
def case():
    scene, c, r = crowd()
    return scene, rays(c, r)


def loop_and_tree(case, monkeypatch):
    scene, (o, d, ray_kind, tmax) = case
    return (queries(scene, o, d, ray_kind, tmax, LOOP, monkeypatch),
            queries(scene, o, d, ray_kind, tmax, TREE, monkeypatch))


def test_tree_hits_are_the_loops_bit_for_bit(case, monkeypatch):
    (loop, loop_blocked), (tree, tree_blocked) = loop_and_tree(case, monkeypatch)
    for a, b in zip(loop, tree):                        # t, kind, prim, u, v
        assert np.array_equal(a, b)
    assert np.array_equal(loop_blocked, tree_blocked)
    t, kind, prim = tree[:3]
    for k in (sg.SPHERE, sg.QUAD, sg.LIGHT, sg.TRIANGLE, sg.NONE):
        assert (kind == k).sum() > 50                   # every kind is exercised
    assert not (prim[kind == sg.SPHERE] == 150).any()   # the coincident twin never wins: sphere 0 does
    edge = prim[1500:1550][kind[1500:1550] == sg.QUAD]
    assert len(edge) > 20 and (edge == 150).all()        # on the shared edge: the lower of the two quads


def test_controls_dropped_leaves_and_a_reversed_tie_are_caught(case, monkeypatch):
    scene, (o, d, ray_kind, tmax) = case
    (loop, _), _ = loop_and_tree(case, monkeypatch)
    leaf_pairs = BoxTree.leaf_pairs

    def drop_one_leaf(self, *args):
        ray, leaf, t_near = leaf_pairs(self, *args)
        keep = leaf % 5 != 3                              # a fifth of the leaves
        return ray[keep], leaf[keep], t_near[keep]
    with monkeypatch.context() as m:
        m.setattr(BoxTree, "leaf_pairs", drop_one_leaf)
        tree, _ = queries(scene, o, d, ray_kind, tmax, TREE, m)
    assert not np.array_equal(loop[2], tree[2])

    first_minimum = box_tree._first_minimum
    with monkeypatch.context() as m:
        m.setattr(box_tree, "_first_minimum", lambda group, value: first_minimum(group, -value)
                  if value.dtype.kind == "i" else first_minimum(group, value))      # ties: the highest number
        tree, _ = queries(scene, o, d, ray_kind, tmax, TREE, m)
    assert not np.array_equal(loop[2], tree[2])


def test_nearest_of_overlapping_spheres_is_the_nearer_surface(monkeypatch):
    # Nested and overlapping balls on the x axis: a ray from the left meets the surface at x = -1.0
    # (the big ball) and from inside the small ball x = 0.35 (its far side), whatever their order.
    balls = [Sphere("small", (0.2, 0, 0), 0.15, 0), Sphere("big", (0, 0, 0), 1.0, 0)]
    balls += [Sphere(f"far {i}", (5.0 + i, 0, 0), 0.4, 0) for i in range(20)]
    scene = Scene(Camera.look_at((0, -3, 0), (0, 0, 0)), [Material("m")], spheres=balls)
    o, d = rows([(-3.0, 0, 0), (0.2, 0, 0), (1.5, 0, 0)]), rows([(1.0, 0, 0)] * 3)
    monkeypatch.setattr(sg, "LOOP_MAX", TREE)
    g = sg.SceneGeometry(scene, plan=Plan())
    assert g.sphere_tree is not None
    t, kind, prim, _, _ = g.intersect(o, d, sg.Counters())
    assert t.tolist() == pytest.approx([2.0, 0.15, 3.1], abs=1e-12)
    assert prim.tolist() == [1, 0, 2] and (kind == sg.SPHERE).all()


def test_every_hit_pair_is_a_candidate():
    """The padded boxes and the slab test's slack never drop a pair the exact test hits: tiny
    spheres far out (docs/hard-cases.md H9), axis-parallel rays, origins on the spheres."""
    rng = np.random.default_rng(7)
    k, n = 400, 4000
    c = rng.uniform(-1, 1, (k, 3)) * 10.0 ** rng.uniform(0, 4, (k, 1))
    r = 10.0 ** rng.uniform(-3, 0, k)
    j = rng.integers(0, k, n)
    d = rng.normal(size=(n, 3))
    d[: n // 4] = np.eye(3)[rng.integers(0, 3, n // 4)]
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = c[j] - 3 * r[j, None] * d + rng.normal(size=(n, 3)) * r[j, None]      # aimed near sphere j
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    o[n // 2:] = (c[j] + r[j, None] * u)[n // 2:]                             # or leaving its surface
    o, d = rows(o), rows(d)
    tree = BoxTree(*padded_boxes(c - r[:, None], c + r[:, None]))
    ray, prim = tree.all_pairs(o, d, np.full(n, np.inf))
    pairs = set(zip(ray.tolist(), prim.tolist()))
    t = intersect_sphere(o, d, rows(c[j]), r[j])                               # each ray against its sphere j
    hit = np.flatnonzero(np.isfinite(t))
    assert len(hit) > n // 3
    assert all((i, j[i]) in pairs for i in hit.tolist())


def seen_lamps_by_loop(seen, o, d, tmax, transmission):
    """The seen-lamps radiance of bulbs one after the other (as engine/lights/seen.py had it), and
    how many bulbs each ray met."""
    total, met = np.zeros(o.shape), np.zeros(o.shape[1], int)
    visible = np.where(transmission[None, :], seen.visible["transmission"][:, None], seen.visible["glossy"][:, None])
    for slot, j in enumerate(seen.bulbs):
        c, r = seen.points.center[:, j], float(seen.points.radius[j])
        away = o - c[:, None]
        outside = dot(away, away) > r * r
        t = intersect_sphere(o, d, c, r, tmax)
        hit = np.flatnonzero(visible[slot] & outside & (t < tmax))
        if len(hit):
            emitted = away.take(hit, axis=1)
            emitted = emitted / np.sqrt(dot(emitted, emitted))
            total[:, hit] += seen.points.le(np.full(len(hit), j), None, -emitted)
            met[hit] += 1
    return total, met


def test_seen_lamps_sum_is_the_loops_bit_for_bit():
    rng = np.random.default_rng(5)
    k, n = 300, 5000
    points = [PointLight(f"b{i}", tuple(rng.uniform(-1, 1, 3)), tuple(rng.uniform(0, 5, 3)),
                         radius=float(rng.uniform(0.05, 0.4)), spot_size=float(rng.choice([0.0, 1.5])), spot_blend=0.3,
                         spot_direction=tuple(rng.normal(size=3)), visible_glossy=bool(i % 3),
                         visible_transmission=bool(i % 4)) for i in range(k)]
    points.append(PointLight("delta", (0, 0, 0), (1, 1, 1)))                  # no radius: never seen
    seen = SeenLamps(Scene(None, [], points=points))
    o = rows(rng.uniform(-1.5, 1.5, (n, 3)))
    d = rng.normal(size=(n, 3))
    d = rows(d / np.linalg.norm(d, axis=1)[:, None])
    tmax = np.where(rng.random(n) < 0.3, np.inf, rng.uniform(0.1, 3, n))
    transmission = rng.random(n) < 0.5
    expected, met = seen_lamps_by_loop(seen, o, d, tmax, transmission)
    got = seen.radiance(o, d, tmax, transmission)
    assert np.array_equal(got, expected)
    assert (met > 0).sum() > n // 5 and (met >= 3).sum() > 50         # sums of 3 and more: the order counts


def test_render_through_the_tree_is_the_loops(monkeypatch):
    rng = np.random.default_rng(9)
    materials = [Material("white"), Material("mirror", MIRROR, (0.9, 0.9, 0.9)),
                 Material("lamp", emission=(3.0, 3.0, 3.0))]
    spheres = [Sphere(f"s{i}", tuple(rng.uniform(-0.8, 0.8, 3) * (1, 1, 0.3) + (0, 0, 0.3)), 0.12, i % 3)
               for i in range(30)]
    tiles = [Quad(f"q{i}", np.array([(x, y, 0.0), (x + 0.15, y, 0.0), (x + 0.15, y + 0.15, 0.0), (x, y + 0.15, 0.0)]), i % 2)
             for i, (x, y) in enumerate(rng.uniform(-1, 0.85, (30, 2)))]
    lights = [AreaLight(f"a{i}", np.array([(x, y, 1.5), (x, y + 0.2, 1.5), (x + 0.2, y + 0.2, 1.5), (x + 0.2, y, 1.5)]),
                        (2.0, 2.0, 2.0), visible_camera=True) for i, (x, y) in enumerate(rng.uniform(-1, 0.8, (20, 2)))]
    bulbs = [PointLight(f"p{i}", tuple(rng.uniform(-1, 1, 3) + (0, 0, 1)), (0.5, 0.5, 0.5), radius=0.05)
             for i in range(12)]
    scene = Scene(Camera.look_at((0, -2.5, 1.5), (0, 0, 0.2)), materials, [], spheres, tiles, lights=lights,
                  points=bulbs, resolution=(16, 16))
    settings = RenderSettings(samples=2, threads=1)
    images = []
    for loop_max in (LOOP, TREE):
        monkeypatch.setattr(sg, "LOOP_MAX", loop_max)
        images.append(render(scene, settings, log=lambda *a: None).image)
    assert np.array_equal(images[0], images[1])
    assert images[1].mean() > 0
