"""Persistent Data (mcrt_addon/persistent.py, engine/pools/kept.py): final renders keep their workers."""
import os

import bpy
import numpy as np
import pytest

from mcrt_addon import bridge, persistent
from rendering import last_report, open_blend, render_operator
from test_render_blender import set_props

from engine.pools.kept import same_but_the_view, same_content
from engine.scene.builtin import cornell_scene as cornell_box


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:
        return f.read().split(")")[-1].split()[0] != "Z"


def test_same_content_compares_values_not_objects():
    a, b = cornell_box(), cornell_box()
    assert a is not b and same_content(a, b) and same_but_the_view(a, b)
    b.meshes[0].vertices[0, 0] += 1e-9                        # one coordinate of one vertex
    assert not same_content(a, b) and not same_but_the_view(a, b)
    c = cornell_box()
    c.resolution = (17, 9)
    c.camera.matrix[0, 3] += 0.1
    assert not same_content(a, c) and same_but_the_view(a, c)
    assert same_content([np.array([np.nan])], [np.array([np.nan])])


@pytest.mark.slow          # five renders in bpy 5.0 (about 6 s)
def test_persistent_data_keeps_workers_and_renders_the_same_images(samples):
    res = (40, 32)
    scene = open_blend(samples["cornell"], res)
    set_props(scene, samples=4, depth=3)
    scene.render.use_persistent_data = False
    fresh = render_operator(scene)
    assert persistent.kept() is None and "persistent_data" not in last_report().stats

    scene.render.use_persistent_data = True
    first = render_operator(scene)
    pool = persistent.kept()
    assert pool is not None and last_report().error is None
    pids = list(last_report().stats["worker_pids"])
    np.testing.assert_array_equal(first, fresh)               # the pool never changes the image

    # an object moves: the same processes prepare the scene again; the image is a fresh render's
    torus = bpy.data.objects["Torus"]
    torus.location.x += 0.2
    moved = render_operator(scene)
    stats = last_report().stats
    assert persistent.kept() is pool and list(stats["worker_pids"]) == pids
    assert stats["renders_on_pool"] == 2 and stats["renders_view_only"] == 0
    built = stats["scenes_prepared"]
    assert not np.array_equal(moved, first)

    # only the camera moves: nothing is prepared again (no BVH rebuild in the workers)
    scene.camera.location.x += 0.05
    view = render_operator(scene)
    stats = last_report().stats
    assert stats["renders_view_only"] == 1 and stats["scenes_prepared"] == built
    scene.render.use_persistent_data = False
    assert np.array_equal(render_operator(scene), view)       # a fresh pool: the same image
    assert persistent.kept() is None                          # Persistent Data off: the kept workers stop
    assert not any(alive(p) for p in pids)
    torus.location.x -= 0.2
    scene.camera.location.x -= 0.05


@pytest.mark.slow
def test_loading_a_file_stops_the_kept_workers(samples):
    scene = open_blend(samples["cornell"], (24, 24))
    set_props(scene, samples=1, depth=1)
    scene.render.use_persistent_data = True
    render_operator(scene)
    pids = list(last_report().stats["worker_pids"])
    assert persistent.kept() is not None and all(alive(p) for p in pids)
    open_blend(samples["cornell"], (24, 24))                  # load_pre handler
    assert persistent.kept() is None
    assert not any(alive(p) for p in pids)


def animate(scene):
    """Frames 1-3 of the cornell sample: the torus moves on every frame (a transform), and on frame 3
    a shape key bends the back wall (a geometry change the exporter must read again)."""
    torus, wall = bpy.data.objects["Torus"], bpy.data.objects["Back"]
    for f in (1, 2, 3):
        torus.location.x = 0.1 * f
        torus.keyframe_insert("location", frame=f)
    wall.shape_key_add(name="Basis")
    bend = wall.shape_key_add(name="Bend")
    for point in bend.data:
        point.co.z += 0.3 * point.co.x
    for f, value in ((1, 0.0), (2, 0.0), (3, 1.0)):
        bend.value = value
        bend.keyframe_insert("value", frame=f)


def frames(scene, starts, count=3):
    """(image, RenderReport, worker pools started) of frames 1..count, one F12 each; `starts`
    counts the pools made (counted_pools)."""
    out = []
    for f in range(1, count + 1):
        scene.frame_set(f)
        before = starts[0]
        out.append((render_operator(scene), last_report(), starts[0] - before))
    return out


def counted_pools(monkeypatch):
    """Count every worker pool the add-on makes (render_engine and persistent go through api.make_pool)."""
    api = bridge.module("api")
    starts, make_pool = [0], api.make_pool

    def counting(*args, **kwargs):
        starts[0] += 1
        return make_pool(*args, **kwargs)
    monkeypatch.setattr(api, "make_pool", counting)
    return starts


@pytest.mark.slow          # nine renders in bpy 5.0
def test_animation_keeps_workers_and_meshes_and_renders_each_frame_as_a_fresh_render(samples, monkeypatch):
    scene = open_blend(samples["cornell"], (32, 24))
    set_props(scene, samples=2, depth=3)
    animate(scene)
    meshes = sum(1 for o in scene.objects if o.type == "MESH")
    starts = counted_pools(monkeypatch)
    scene.render.use_persistent_data = False
    fresh = frames(scene, starts)
    assert [r.export["meshes_read"] for _, r, _ in fresh] == [meshes] * 3         # every frame reads every mesh
    assert [n for _, _, n in fresh] == [1, 1, 1]                                 # and starts its own workers

    scene.render.use_persistent_data = True
    kept = frames(scene, starts)
    # one pool for the animation: started once, the same processes, one render and one export per frame
    assert [n for _, _, n in kept] == [1, 0, 0]
    assert len({tuple(r.stats["worker_pids"]) for _, r, _ in kept}) == 1
    assert [r.stats["renders_on_pool"] for _, r, _ in kept] == [1, 2, 3]
    # the moved torus is not read again; the wall, whose shape key is animated, is on every frame
    # (Blender's depsgraph flags its geometry as updated on each frame, not only where it changes)
    assert [r.export["meshes_read"] for _, r, _ in kept] == [meshes, 1, 1]
    for (a, _, _), (b, _, _) in zip(fresh, kept):
        np.testing.assert_array_equal(a, b)                  # bit for bit a fresh render's frame
    assert not np.array_equal(kept[1][0], kept[2][0])

    # an edit between two F12 presses (the mesh's data, not a key or modifier) reaches the kept depsgraph
    torus = bpy.data.objects["Torus"].data
    original = np.zeros(len(torus.vertices) * 3, np.float32)
    torus.vertices.foreach_get("co", original)
    torus.vertices.foreach_set("co", original * np.tile(np.float32([1.0, 1.0, 1.5]), len(torus.vertices)))
    torus.update()
    edited = render_operator(scene)
    assert last_report().export["meshes_read"] == 2 and last_report().stats["renders_on_pool"] == 4
    scene.render.use_persistent_data = False
    np.testing.assert_array_equal(edited, render_operator(scene))
    assert not np.array_equal(edited, kept[2][0])
    torus.vertices.foreach_set("co", original)                  # exactly as it was
    torus.update()
    scene.render.use_persistent_data = True

    # control: a cache that never forgets renders frame 3 with the unbent wall
    persistent.free()
    monkeypatch.setattr(persistent, "forget_meshes", lambda cache, names: None)
    stale = frames(scene, starts)
    assert [r.export["meshes_read"] for _, r, _ in stale] == [meshes, 0, 0]
    np.testing.assert_array_equal(stale[1][0], fresh[1][0])
    assert not np.array_equal(stale[2][0], fresh[2][0])
    scene.render.use_persistent_data = False
    render_operator(scene)                                   # the kept workers stop


def test_kept_mesh_arrays_keep_their_sphere_fit_and_forget_it_with_them(scene, ms, monkeypatch):
    """The exporter keeps a mesh's implicit-sphere fit with its cached arrays (a moved sphere is not
    fitted again) and fits it again whenever the arrays are read again."""
    import mcrt_addon.export as exporter
    from mcrt_addon.viewport import forget_meshes
    from tests.addon.exporting import export

    ball = ms.mesh_object(scene, "Ball", lambda bm: ms.uv_sphere(bm, 0.5, 32, 16), ms.diffuse("D", (0.5, 0.5, 0.5)))
    cache = {}
    first = export(mesh_cache=cache)
    assert [s.radius for s in first.scene.spheres] == [pytest.approx(0.5, rel=1e-5)]
    stale = {k: v for k, v in cache.items() if k[-1] == "sphere_fit"}
    assert len(stale) == 1

    def no_fit(*args):
        raise AssertionError("a kept mesh was fitted again")
    ball.location.x += 0.3                                    # moved only: arrays and fit from the cache
    with monkeypatch.context() as m:
        m.setattr(exporter, "sphere_fit", no_fit)
        moved = export(mesh_cache=cache)
    assert moved.info["meshes_read"] == 0
    assert moved.scene.spheres[0].radius == first.scene.spheres[0].radius
    assert moved.scene.spheres[0].center[0] == pytest.approx(first.scene.spheres[0].center[0] + 0.3)

    # the mesh grows: the add-on forgets its arrays (persistent.mesh_cache); the fit goes with them,
    # and is fitted again even when an old fit is left in the cache (control: it would be 0.5)
    for v in ball.data.vertices:
        v.co *= 2.0
    ball.data.update()
    forget_meshes(cache, {"Ball"})
    assert not any(k[-1] == "sphere_fit" for k in cache)
    cache.update(stale)
    grown = export(mesh_cache=cache)
    assert grown.info["meshes_read"] == 1
    assert [s.radius for s in grown.scene.spheres] == [pytest.approx(1.0, rel=1e-5)]
