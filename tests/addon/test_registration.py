"""Registration, properties, panels."""
import bpy
import pytest

import mcrt_addon
from mcrt_addon import properties


def engine_ids():
    """bl_idnames of the registered render engines (registered classes appear in bpy.types)."""
    return {getattr(c, "bl_idname", None) for c in bpy.types.RenderEngine.__subclasses__()
            if getattr(c, "is_registered", False)}


def test_register_unregister_register(addon):
    assert "TNCG15_MC" in engine_ids()
    mcrt_addon.unregister()
    try:
        assert not hasattr(bpy.types.Scene, "tncg15")
        assert not hasattr(bpy.types.Object, "tncg15")
        assert "TNCG15_MC" not in engine_ids()
        assert not hasattr(bpy.types, "RENDER_PT_tncg15_sampling")
        lent = [p for p in bpy.types.Panel.__subclasses__()
                if "TNCG15_MC" in getattr(p, "COMPAT_ENGINES", ()) and not p.__module__.startswith("mcrt_addon")]
        assert lent == []
    finally:
        mcrt_addon.register()
    assert "TNCG15_MC" in engine_ids()
    assert hasattr(bpy.types, "RENDER_PT_tncg15_sampling")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "TNCG15_MC"
    assert scene.render.engine == "TNCG15_MC"


def test_engine_class_flags(addon):
    cls = mcrt_addon.render_engine.TNCG15RenderEngine
    assert cls.bl_idname == "TNCG15_MC" and cls.bl_label == "TNCG15 MC"
    assert cls.bl_use_shading_nodes_custom is False   # Cycles shader nodes stay visible


def test_scene_settings_defaults_and_conversion(empty_scene):
    from mcrt_addon import bridge
    props = empty_scene.tncg15
    props.samples, props.shadow_rays, props.seed = 7, 3, 42
    props.max_depth, props.russian_roulette, props.rr_start_depth = 5, False, 2
    props.fresnel, props.threads, props.accelerator, props.tile_size = "EXACT", 1, "EMBREE", 32
    s = props.to_settings(bridge.settings_class())
    assert (s.samples, s.shadow_rays, s.seed, s.max_depth) == (7, 3, 42, 5)
    assert (s.russian_roulette, s.rr_start_depth, s.fresnel) == (False, 2, "exact")
    assert (s.threads, s.accelerator, s.tile_size) == (1, "embree", 32)
    s.validate()


def test_accelerator_enum_offers_all_four():
    ids = [item[0] for item in properties.ACCELERATOR_ITEMS]
    assert ids == ["AUTO", "EMBREE", "OCTREE", "BRUTE"]


def test_object_sphere_option(empty_scene):
    me = bpy.data.meshes.new("m")
    ob = bpy.data.objects.new("o", me)
    assert ob.tncg15.implicit_sphere == "AUTO"
    ob.tncg15.implicit_sphere = "NEVER"
    with pytest.raises(TypeError):
        ob.tncg15.implicit_sphere = "SOMETIMES"


def test_panels_registered_and_polled(empty_scene):
    names = ["RENDER_PT_tncg15_sampling", "RENDER_PT_tncg15_light_paths", "RENDER_PT_tncg15_performance",
             "OBJECT_PT_tncg15"]
    for name in names:
        assert hasattr(bpy.types, name), name
    panel = getattr(bpy.types, "RENDER_PT_tncg15_sampling")

    class Ctx:
        engine = "TNCG15_MC"
    assert panel.poll(Ctx)
    Ctx.engine = "CYCLES"
    assert not panel.poll(Ctx)
    # generic panels (e.g. output / dimensions) are lent our engine id
    lent = [p.__name__ for p in bpy.types.Panel.__subclasses__() if "TNCG15_MC" in getattr(p, "COMPAT_ENGINES", ())]
    assert any(n.startswith("RENDER_PT_format") or n.startswith("RENDER_PT_output") for n in lent), lent


class RecordingLayout:
    """Stands in for a UILayout: records the properties and operators drawn."""

    def __init__(self, seen):
        self.seen = seen

    def __getattr__(self, name):                    # use_property_split, active, ...: accepted
        return None

    def __setattr__(self, name, value):
        if name == "seen":
            object.__setattr__(self, name, value)

    def column(self, **kw):
        return self

    row = column

    def prop(self, data, name, **kw):
        self.seen.append(name)

    def operator(self, name, **kw):
        self.seen.append(name)

    def label(self, **kw):
        pass


def test_sampling_panel_has_cycles_sub_panels_and_draws_every_setting_once(empty_scene):
    """Render Properties > Sampling as Cycles: Viewport, Render, Lights, Advanced sub-panels (in that
    order of registration, which is the order Blender shows them)."""
    import mcrt_addon.ui as ui
    children = [c for c in ui.classes if getattr(c, "bl_parent_id", "") == "RENDER_PT_tncg15_sampling"]
    assert [c.bl_label for c in children] == ["Viewport", "Render", "Lights", "Advanced"]

    class Ctx:
        engine = "TNCG15_MC"
        scene = empty_scene
    seen = []
    from types import SimpleNamespace
    for cls in children:
        cls.draw(SimpleNamespace(layout=RecordingLayout(seen)), Ctx)
    assert sorted(seen) == sorted(["viewport_samples", "use_noise_target", "noise_target", "samples", "min_samples",
                                   "time_limit", "adaptive", "tncg15.estimate_render_time", "shadow_rays",
                                   "sampler", "seed", "use_animated_seed"])


def test_film_panel_is_cycles_film_panel(empty_scene):
    """Render Properties > Film as Cycles: Exposure, then Pixel Filter (type, width) and Transparent
    (Blender's own scene.render.film_transparent in its header), closed by default."""
    import mcrt_addon.ui as ui
    film = ui.RENDER_PT_tncg15_film
    children = [c for c in ui.classes if getattr(c, "bl_parent_id", "") == "RENDER_PT_tncg15_film"]
    assert film.bl_label == "Film" and film.bl_options == {"DEFAULT_CLOSED"}
    assert [c.bl_label for c in children] == ["Pixel Filter", "Transparent"]

    class Ctx:
        engine = "TNCG15_MC"
        scene = empty_scene
    seen = []
    from types import SimpleNamespace
    for cls in (film, *children):
        for method in ("draw_header", "draw"):
            if hasattr(cls, method):
                getattr(cls, method)(SimpleNamespace(layout=RecordingLayout(seen)), Ctx)
    assert seen == ["film_exposure", "pixel_filter_type", "filter_width", "film_transparent"]
    # a new file starts with Cycles' film: Blackman-Harris 1.5 px, exposure 1, opaque
    props = empty_scene.tncg15
    assert (props.pixel_filter_type, props.filter_width, props.film_exposure) == ("BLACKMAN_HARRIS", 1.5, 1.0)
    settings = props.to_settings(__import__("mcrt_addon").bridge.settings_class())
    assert (settings.pixel_filter, settings.filter_width, settings.film_transparent) == ("blackman-harris", 1.5, False)
    empty_scene.render.film_transparent = True
    assert props.to_settings(type(settings)).film_transparent is True
    empty_scene.render.film_transparent = False


def test_animated_seed_hashes_the_frame(empty_scene):
    """Use Animated Seed: the seed the tracer gets is Cycles' hash of (frame, seed); off: the seed."""
    from mcrt_addon import bridge
    props, Settings = empty_scene.tncg15, bridge.settings_class()
    props.seed = 5
    frame = empty_scene.frame_current
    assert props.to_settings(Settings).seed == 5
    props.use_animated_seed = True
    try:
        first = props.to_settings(Settings).seed
        empty_scene.frame_current = frame + 1
        second = props.to_settings(Settings).seed
        assert first != second and first != 5
        assert first == bridge.settings_table().animated_seed(5, frame)
        # two frames of a still scene: other noise with the toggle on, the same image with it off
        import numpy as np
        from engine.api import render
        from tests.scenes import object_in_uniform_background
        still = object_in_uniform_background("diffuse", color=0.5, resolution=(8, 8))

        def image_at(f):
            empty_scene.frame_current = f
            settings = props.to_settings(Settings)
            settings.samples, settings.threads, settings.parallelism = 4, 1, "threads"
            return render(still, settings, log=lambda *a: None).image
        assert not np.array_equal(image_at(frame), image_at(frame + 1))
        props.use_animated_seed = False
        assert np.array_equal(image_at(frame), image_at(frame + 1))
    finally:
        empty_scene.frame_current = frame
        props.property_unset("use_animated_seed")
        props.property_unset("seed")



def test_preferences_link_the_user_guide(addon):
    """Preferences > Add-ons > TNCG15 MC: a Documentation button opening the user guide (in a
    repository checkout docs/user-guide.md, in the zips their docs/ copy), and the fields drawn with
    property split (labels left: never cut short)."""
    import os
    import types
    from mcrt_addon import worker_python
    guide = worker_python.documentation_path()
    assert guide is not None and os.path.isfile(guide) and guide.endswith(os.path.join("docs", "user-guide.md"))
    operators, props = [], []

    class Layout(RecordingLayout):
        use_property_split = None

        def operator(self, name, **kw):
            op = types.SimpleNamespace(url=None)
            operators.append((name, kw.get("text"), op))
            return op
    layout = Layout(props)
    prefs = types.SimpleNamespace(worker_python="", render_cluster="", start_workers_ahead=True)
    worker_python.TNCG15Preferences.draw(types.SimpleNamespace(layout=layout, **vars(prefs)), None)
    assert props == ["worker_python", "render_cluster", "start_workers_ahead"]
    assert [(n, t) for n, t, _ in operators] == [("tncg15.install_denoiser", None), ("wm.url_open", "Documentation")]
    assert operators[1][2].url == "file://" + guide
