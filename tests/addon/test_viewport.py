"""What the bpy 5.0 module can test of the viewport (it runs in background mode: Blender never
draws a 3D viewport, never calls view_update / view_draw itself, and every gpu drawing call raises
SystemError; docs/cluster-and-viewport.md §B3).  Tested here with Blender's own data instead:

* the viewport camera built from a projection and view matrix (Blender's calc_matrix_camera)
  sees exactly what the exporter's camera sees (pixel directions, shift included);
* depsgraph updates, captured in a depsgraph_update_post handler as Blender hands them to
  view_update, are sorted into "view" and "scene" changes;
* view_update / view_draw bodies, called with a stub engine and context inside that handler:
  moving an object or the camera reads no mesh, editing a mesh reads that mesh only, a camera move
  restarts the workers without a new export, the header shows samples and noise, and freeing the
  engine stops the workers;
* material previews (bl_use_preview) render with TNCG15 MC at PREVIEW_SAMPLES.

Drawing (gpu textures, colour management, the Rendered viewport itself) is tested in Blender
3.4's window under Xvfb (test_viewport_blender34.py).
"""
import time
from types import SimpleNamespace

import bpy
import numpy as np
import pytest

from tests.file_safety import alive


@pytest.fixture
def point_light(addon, make_samples_module, tmp_path):
    path = make_samples_module.make("point_light", str(tmp_path), resolution=(40, 30))
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    scene.render.engine = "TNCG15_MC"
    return scene


def test_view_camera_sees_what_the_exporter_camera_sees(point_light):
    from engine.scene.model import Camera
    from mcrt_addon.export.camera import export_camera, pixel_directions
    from mcrt_addon.viewport import camera_from_matrices
    scene = point_light
    cam = scene.camera
    cam.data.shift_x, cam.data.shift_y, cam.data.lens = 0.1, -0.07, 35.0
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for w, h in ((40, 30), (30, 40)):
        P = cam.calc_matrix_camera(depsgraph, x=w, y=h)
        params = camera_from_matrices(P, cam.matrix_world.inverted())
        ours = pixel_directions(Camera(**params), w, h)
        theirs = pixel_directions(export_camera(cam, (w, h), Camera=Camera, warnings=[]), w, h)
        np.testing.assert_allclose(ours, theirs, atol=1e-6)
    cam.data.type = "ORTHO"
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert camera_from_matrices(cam.calc_matrix_camera(depsgraph, x=40, y=30), cam.matrix_world.inverted()) is None


class Handler:
    """Calls `fn(depsgraph)` inside depsgraph_update_post, where depsgraph.updates is filled."""

    def __init__(self, fn):
        self.fn, self.results = fn, []

    def __call__(self, scene, depsgraph):
        self.results.append(self.fn(depsgraph))

    def __enter__(self):
        bpy.app.handlers.depsgraph_update_post.append(self)
        return self

    def __exit__(self, *exc):
        bpy.app.handlers.depsgraph_update_post.remove(self)


def edit(fn):
    fn()
    bpy.context.view_layer.update()


def test_depsgraph_updates_are_sorted_into_view_and_scene_changes(point_light):
    from mcrt_addon.viewport import classify
    scene = point_light
    box = scene.objects["Box"]
    bpy.context.view_layer.update()          # the engine switch of the fixture: a Scene update
    with Handler(lambda dg: classify(dg.updates)) as h:
        edit(lambda: setattr(scene.camera, "location", scene.camera.location + type(scene.camera.location)((0, 0.1, 0))))
        edit(lambda: setattr(scene.camera.data, "lens", 40.0))
        edit(lambda: setattr(box, "location", (0.3, 0.3, 0.3)))
        edit(lambda: setattr(scene.objects["Bulb"].data, "energy", 80.0))

        def move_vertex():
            box.data.vertices[0].co.x += 0.01
            box.data.update()
        edit(move_vertex)
    kinds = [r[0] for r in h.results]
    assert kinds == ["view", "view", "scene", "scene", "scene"], h.results
    assert h.results[2][1] == set(), "a transform changes no geometry"
    assert box.name in h.results[4][1] or box.data.name in h.results[4][1], h.results[4]


def stub_engine():
    stats, updates = [], []
    return SimpleNamespace(_readable=lambda exc: None, update_stats=lambda a, b: stats.append(b),
                           bind_display_space_shader=None, unbind_display_space_shader=None, stats=stats,
                           tag_update=lambda: updates.append(1), updates=updates)


def stub_context(scene, width=40, height=30, lens=None):
    cam = scene.camera
    depsgraph = bpy.context.evaluated_depsgraph_get()
    return SimpleNamespace(region=SimpleNamespace(width=width, height=height),
                           region_data=SimpleNamespace(window_matrix=cam.calc_matrix_camera(depsgraph, x=width, y=height),
                                                       view_matrix=cam.matrix_world.inverted(),
                                                       view_perspective="PERSP"),
                           space_data=None)


def test_view_update_reads_meshes_only_when_their_geometry_changes(point_light, monkeypatch):
    import mcrt_addon.export as export
    from mcrt_addon import viewport
    scene = point_light
    reads = []
    original = export.mesh_arrays
    monkeypatch.setattr(export, "mesh_arrays", lambda me: reads.append(me.name) or original(me))
    engine = stub_engine()
    scene.tncg15.viewport_samples = 4
    ctx = stub_context(scene)
    bpy.context.view_layer.update()
    viewport.view_update(engine, ctx, bpy.context.evaluated_depsgraph_get())     # entering Rendered
    st = engine.viewport_state
    try:
        assert st.message is None and st.exports == 1, st.message
        n_meshes = len(reads)
        assert n_meshes >= 3, reads
        with Handler(lambda dg: viewport.view_update(engine, ctx, dg)):
            edit(lambda: setattr(scene.objects["Box"], "location", (0.3, 0.2, 0.302)))
            assert st.exports == 2 and len(reads) == n_meshes, "a transform must not read meshes"
            edit(lambda: setattr(scene.camera.data, "lens", 45.0))
            assert st.exports == 2, "a camera edit re-exports nothing (view_draw sends the view)"

            def move_vertex():
                scene.objects["Box"].data.vertices[0].co.z += 0.01
                scene.objects["Box"].data.update()
            edit(move_vertex)
            assert st.exports == 3 and reads[n_meshes:] == [scene.objects["Box"].data.name], reads[n_meshes:]
        # view_draw: the view changed (lens 45): only the camera goes to the workers
        gen = st.workers.gen
        viewport.view_draw(engine, stub_context(scene), bpy.context.evaluated_depsgraph_get())
        assert st.workers.gen == gen + 1 and st.exports == 3
        deadline = time.perf_counter() + 60
        while not st.workers.converged() and time.perf_counter() < deadline:
            time.sleep(0.05)
        viewport.view_draw(engine, ctx, bpy.context.evaluated_depsgraph_get())  # back: view again
        deadline = time.perf_counter() + 60
        while not st.workers.converged() and time.perf_counter() < deadline:
            time.sleep(0.05)
        viewport.view_draw(engine, ctx, bpy.context.evaluated_depsgraph_get())
        assert engine.stats[-1].startswith("Sample 4/4 | Noise ±"), engine.stats[-3:]
        _, rgba, samples, *_ = st.workers.snapshot()
        assert samples == 4 and rgba.shape == (30, 40, 4) and rgba[..., :3].mean() > 0.02
        assert st.workers.picture().tag == st.key, "the picture carries the view it was rendered for"
        # Pixel Size 2 (scene.render.preview_pixel_size as RenderEngine.get_preview_pixel_size
        # reads it): the view's own frame at half its resolution, drawn over the whole region
        engine.get_preview_pixel_size = lambda scene_: 2
        viewport.export(engine, st, ctx, bpy.context.evaluated_depsgraph_get())
        deadline = time.perf_counter() + 60
        while not st.workers.converged() and time.perf_counter() < deadline:
            time.sleep(0.05)
        picture = st.workers.picture()
        assert picture.divider == 2 and picture.rgba.shape == (15, 20, 4) and picture.samples == 4, picture[2:]
    finally:
        pids = st.workers.pids if st.workers else []
        viewport.free(engine)
    deadline = time.perf_counter() + 15            # they stop on a thread of their own: a guard only
    while any(alive(p) for p in pids) and time.perf_counter() < deadline:
        time.sleep(0.02)
    assert pids and not any(alive(p) for p in pids), "freeing the engine must stop its workers"


def test_view_update_reports_problems_in_the_header(point_light):
    from mcrt_addon import viewport
    scene = point_light
    engine = stub_engine()
    ctx = stub_context(scene)
    scene.objects["Box"].location.x = float("nan")
    bpy.context.view_layer.update()
    viewport.view_update(engine, ctx, bpy.context.evaluated_depsgraph_get())
    viewport.view_draw(engine, ctx, bpy.context.evaluated_depsgraph_get())
    viewport.free(engine)
    assert "Object 'Box'" in engine.stats[-1] and "NaN" in engine.stats[-1], engine.stats


@pytest.mark.slow          # 2-5 s (renders, subprocesses): make test-slow, which .ci/run runs too
def test_material_preview_renders_with_tncg15(addon):
    import mcrt_addon.render_engine as engine_module
    bpy.ops.wm.read_factory_settings(use_empty=False)
    bpy.context.scene.render.engine = "TNCG15_MC"
    mat = bpy.data.materials.new("Red")
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = (0.8, 0.05, 0.05, 1.0)
    with engine_module.capture_reports() as reports:
        mat.asset_generate_preview()            # synchronous in the bpy module
    assert len(reports) == 1 and reports[0].error is None, reports
    r = reports[0]
    assert r.stats["samples"] == engine_module.PREVIEW_SAMPLES and r.resolution == (128, 128)
    size = tuple(mat.preview.image_size)
    px = np.array(mat.preview.image_pixels_float[:]).reshape(size[1], size[0], 4)
    centre = px[size[1] // 2 - 10:size[1] // 2 + 10, size[0] // 2 - 10:size[0] // 2 + 10, :3].mean(axis=(0, 1))
    # the red material shows, under the specular layer's highlight of the preview's lamps (a
    # Principled BSDF; Cycles 5.0 renders this centre 0.85 / 0.44 / 0.41)
    assert centre[0] > 1.6 * centre[1] and centre[0] > 1.6 * centre[2], centre


def test_a_scene_without_camera_renders_in_a_perspective_viewport(point_light):
    from mcrt_addon import viewport
    scene = point_light
    engine = stub_engine()
    ctx = stub_context(scene)                   # the view where the camera was
    bpy.data.objects.remove(scene.camera)
    bpy.context.view_layer.update()
    viewport.view_update(engine, ctx, bpy.context.evaluated_depsgraph_get())
    st = engine.viewport_state
    try:
        assert st.message is None and st.exports == 1, st.message
        deadline = time.perf_counter() + 60
        while st.workers.snapshot()[1] is None and time.perf_counter() < deadline:
            time.sleep(0.05)
        assert st.workers.snapshot()[1] is not None
    finally:
        viewport.free(engine)


def test_an_orthographic_view_says_so_and_a_perspective_view_renders_again(point_light):
    from mcrt_addon import viewport
    scene = point_light
    engine = stub_engine()
    persp = stub_context(scene)
    ortho = stub_context(scene)
    P = persp.region_data.window_matrix.copy()
    P[3][2], P[3][3] = 0.0, 1.0                 # an orthographic projection's last row
    ortho.region_data.window_matrix = P
    bpy.context.view_layer.update()
    viewport.view_update(engine, ortho, bpy.context.evaluated_depsgraph_get())
    try:
        viewport.view_draw(engine, ortho, bpy.context.evaluated_depsgraph_get())
        assert "orthographic" in engine.stats[-1] and engine.viewport_state.exports == 0, engine.stats
        viewport.view_draw(engine, persp, bpy.context.evaluated_depsgraph_get())   # Numpad 5
        assert engine.updates == [1], "view_draw must ask for a view_update (export) once"
        viewport.view_draw(engine, persp, bpy.context.evaluated_depsgraph_get())
        assert engine.updates == [1]
        viewport.view_update(engine, persp, bpy.context.evaluated_depsgraph_get())  # what Blender does next
        assert engine.viewport_state.exports == 1 and engine.viewport_state.message is None
    finally:
        viewport.free(engine)


def test_viewport_settings_sit_under_sampling_as_in_cycles(addon):
    panel = bpy.types.RENDER_PT_tncg15_sampling_viewport
    assert panel.bl_parent_id == "RENDER_PT_tncg15_sampling" and panel.bl_label == "Viewport"
    drawn = []

    class Layout:
        use_property_split = use_property_decorate = None

        def column(self, **kw):
            return self

        def prop(self, data, name, **kw):
            drawn.append((name, kw.get("text")))

    panel.draw(SimpleNamespace(layout=Layout()), SimpleNamespace(scene=bpy.context.scene))
    assert drawn == [("viewport_samples", "Max Samples")]
    assert bpy.context.scene.tncg15.viewport_samples == 32
    assert "TNCG15_MC" in bpy.types.MATERIAL_PT_preview.COMPAT_ENGINES      # the preview panel shows
    assert bpy.types.RenderEngine.bl_rna.properties["bl_use_preview"] is not None
    from mcrt_addon.render_engine import TNCG15RenderEngine
    assert TNCG15RenderEngine.bl_use_preview


def test_a_texture_let_go_of_on_another_thread_is_freed_on_the_ui_thread():
    """GPU objects may only be freed where Blender's GL context is: a ViewportState closed or
    collected on a worker's thread hands its texture to the UI thread (viewport.GPU_ORPHANS)."""
    import threading
    import weakref as wr
    from mcrt_addon import viewport as vp

    class Texture:                               # stands in for a gpu.types.GPUTexture
        pass
    st = vp.ViewportState()
    st.texture = Texture()
    gone = wr.ref(st.texture)
    worker = threading.Thread(target=st.close)
    worker.start()
    worker.join()
    assert st.texture is None and gone() is not None          # not freed on the worker's thread
    vp.free_orphans()                                          # the UI thread's next callback
    assert gone() is None
    st.texture = Texture()                                     # control: closed on the UI thread
    gone = wr.ref(st.texture)
    st.close()
    assert gone() is None and not vp.GPU_ORPHANS
