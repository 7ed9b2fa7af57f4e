"""A scene's image does not depend on where it stands (engine/scene/tracing_origin.py).

The built-in Cornell room (a unit room: walls of 2 units, a 5,000-triangle torus, a mirror and a
glass ball, a square lamp) is moved by 1e5, 5e5 and 1e6 units along every axis.  In world
coordinates Embree's float32 rounds its vertices to 1/32 unit there and the spawn offsets grow to
half a unit: black disks under the balls.  Traced relative to the camera it renders as at the origin.
"""
import copy

import numpy as np
import pytest

from engine.api import render
from engine.core.settings import RenderSettings
from engine.rendering.session import PreparedScene
from engine.scene.builtin import cornell_scene
from engine.scene.tracing_origin import FAR, moved, scene_extent, tracing_origin
from tests.addon.imagecompare import compare_runs

OFFSETS = (1e5, 5e5, 1e6)
RES, SPP, K = 32, 16, 4


def translated(scene, offset):
    """The scene moved by `offset` (3,), as a Blender file with the offset in the object transforms."""
    scene = copy.deepcopy(scene)
    offset = np.asarray(offset, dtype=np.float64)
    for mesh in scene.meshes:
        mesh.vertices = mesh.vertices + offset
    for sphere in scene.spheres:
        sphere.center = tuple(np.asarray(sphere.center) + offset)
    for quad in scene.quads:
        quad.corners = np.asarray(quad.corners) + offset
    scene.camera.matrix = scene.camera.matrix.copy()
    scene.camera.matrix[:3, 3] += offset
    return scene


def images(scene, seeds):
    return np.stack([render(copy.deepcopy(scene), RenderSettings(samples=SPP, seed=seed), log=lambda *a: None).image
                     for seed in seeds])


@pytest.fixture(scope="module")
def origin_runs():
    return images(cornell_scene((RES, RES)), range(1, K + 1))


@pytest.mark.parametrize("offset", [pytest.param(OFFSETS[0], marks=pytest.mark.slow), OFFSETS[1],
                                    pytest.param(OFFSETS[2], marks=pytest.mark.slow)])   # 0.35 s each
def test_far_room_equals_the_origin_room_within_noise(offset, origin_runs):
    far = images(translated(cornell_scene((RES, RES)), (offset,) * 3), range(11, K + 11))
    result = compare_runs(far, origin_runs, tau=0.0)
    assert result.passed, result.summary()


@pytest.mark.parametrize("offset", OFFSETS)
def test_far_room_with_the_same_seed_is_the_origin_room_but_for_rounding(offset, origin_runs):
    """With the same random numbers the far room's paths are the origin room's: only float rounding
    (positions relative to the camera, not to the world origin) can tell them apart."""
    far = images(translated(cornell_scene((RES, RES)), (offset,) * 3), [1])[0]
    differs = np.abs(far - origin_runs[0]).max(axis=-1) > 1e-4
    assert differs.mean() < 0.01, f"{differs.sum()} of {differs.size} pixels differ"


def test_control_a_room_rendered_with_its_offset_in_float32_fails(origin_runs):
    """CONTROL: the comparison sees the far room's artefacts when it is traced in world coordinates."""
    far = translated(cornell_scene((RES, RES)), (5e5,) * 3)
    import engine.rendering.session as session
    original = session.tracing_origin
    session.tracing_origin = lambda scene: None
    try:
        runs = images(far, range(11, K + 11))
    finally:
        session.tracing_origin = original
    assert not compare_runs(runs, origin_runs, tau=0.0).passed


def test_scenes_near_the_origin_are_traced_as_they_are():
    """The built-in room is within FAR extents of the origin: no copy, world coordinates (today's images)."""
    scene = cornell_scene((8, 8))
    scene.validate()
    assert tracing_origin(scene) is None
    assert PreparedScene(scene, RenderSettings(samples=1), log=lambda *a: None).scene is scene


def test_far_scenes_are_traced_relative_to_the_camera():
    scene = translated(cornell_scene((8, 8)), (5e5, -5e5, 5e5))
    scene.validate()
    origin = tracing_origin(scene)
    assert np.array_equal(origin, scene.camera.matrix[:3, 3])
    local = moved(scene, origin)
    assert np.abs(local.camera.matrix[:3, 3]).max() == 0.0
    assert np.abs(local.meshes[0].vertices).max() < FAR * scene_extent(scene)
    assert np.abs(scene.meshes[0].vertices).min() > 4e5          # the scene itself is not changed
    prepared = PreparedScene(scene, RenderSettings(samples=1), log=lambda *a: None)
    prepared.set_view(scene.camera, (4, 4))                      # the viewport sends world coordinates
    assert np.abs(prepared.scene.camera.matrix[:3, 3]).max() == 0.0 and prepared.scene.resolution == (4, 4)


def test_every_scene_field_is_known_to_the_move():
    """tracing_origin.moved moves the positions of the camera, meshes, spheres, quads, Area and point
    lights; the other fields hold none.  A new field of Scene must be placed in one group or the other."""
    import dataclasses
    from engine.scene.model import Scene
    moved_fields = {"camera", "meshes", "spheres", "quads", "lights", "points"}
    no_positions = {"materials", "background", "resolution", "name", "suns", "textures", "cycles_version",
                    "mist", "environment"}  # mist: distances from the camera; environment: directions
    assert {f.name for f in dataclasses.fields(Scene)} == moved_fields | no_positions
