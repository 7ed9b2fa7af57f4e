"""A process reuses its last accelerator for the same triangles (engine/geometry/accel/__init__.py)."""
import dataclasses

import numpy as np

from engine.core.settings import RenderSettings
from engine.geometry.accel import build_accelerator
from engine.rendering.session import PreparedScene
from engine.scene.builtin import cornell_scene


def test_same_triangles_reuse_the_bvh_and_other_triangles_build_a_new_one():
    tris = np.random.default_rng(1).random((50, 3, 3))
    first = build_accelerator("brute", tris)
    assert build_accelerator("brute", tris.copy()) is first            # equal content, another array
    moved = tris.copy()
    moved[7, 1, 2] += 1e-6
    other = build_accelerator("brute", moved)
    assert other is not first
    assert build_accelerator("octree", moved) is not other              # another kind of accelerator


def test_a_light_edit_keeps_the_bvh_and_renders_as_a_fresh_build():
    settings = RenderSettings(samples=2, max_depth=3, accelerator="embree")
    scene = cornell_scene((24, 24))
    a = PreparedScene(scene, settings, log=lambda *x: None)
    lit = dataclasses.replace(scene, background=(0.2, 0.2, 0.2))      # meshes unchanged
    b = PreparedScene(lit, settings, log=lambda *x: None)
    assert b.geometry.accelerator is a.geometry.accelerator
    o = np.array([[0.0], [0.0], [0.5]]).repeat(64, axis=1)
    d = np.random.default_rng(2).normal(size=(3, 64))
    d /= np.linalg.norm(d, axis=0)
    from engine.geometry.accel import ACCELERATOR_CLASSES
    fresh = ACCELERATOR_CLASSES["embree"](b.geometry.triangles)
    from engine.core.vec import aos
    dt = fresh.ray_dtype
    for x, y in zip(fresh.intersect(aos(o, dt), aos(d, dt), np.full(64, np.inf)),
                    b.geometry.accelerator.intersect(aos(o, dt), aos(d, dt), np.full(64, np.inf))):
        np.testing.assert_array_equal(x, y)
