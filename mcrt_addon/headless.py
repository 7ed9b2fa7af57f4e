"""What a command-line run of Blender needs from the add-on: registration once, and EXR output
settings.  Used by the add-on CLI (cli.py) and its benchmarks (bench.py, bench_estimators.py)."""


def set_exr_output(scene, path):
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    settings.color_mode = "RGBA" if scene.render.film_transparent else "RGB"   # Film > Transparent: alpha
    settings.exr_codec = "ZIP"
    scene.render.filepath = path
    scene.render.use_file_extension = False
    scene.render.use_compositing = False
    scene.render.use_sequencer = False


def ensure_registered(mcrt_addon):
    import bpy
    if not (hasattr(bpy.types.Scene, "tncg15") and mcrt_addon.render_engine.TNCG15RenderEngine.is_registered):
        mcrt_addon.register()



CAPTURE_ENGINE = "TNCG15_MC_EXPORT_CAPTURE"
_capture = {}                   # the capturing engine's class, and one call's kwargs and result


def export_as_rendered(scene, **export_kwargs):
    """export_scene (mcrt_addon/export) of the depsgraph that F12 and Cycles render, not of the
    viewport's: modifiers at their render settings (a Subdivision Surface's Render levels, not its
    Levels Viewport), objects and modifiers by their render visibility.  bpy gives that depsgraph
    only to a render engine, so a capturing engine "renders" the scene once (drawing nothing) and
    exports what it is given.  For harnesses that compare with Cycles (bench_estimators.py,
    tests/addon/rendering.py): bpy.context.evaluated_depsgraph_get() is the viewport's."""
    import bpy
    if "engine" not in _capture:
        from .export import export_scene

        class ExportCapture(bpy.types.RenderEngine):
            bl_idname = CAPTURE_ENGINE
            bl_label = "TNCG15 MC export capture"

            def render(self, depsgraph):
                try:
                    _capture["result"] = export_scene(depsgraph, **_capture["kwargs"])
                except BaseException as error:  # re-raised by export_as_rendered
                    _capture["error"] = error

        bpy.utils.register_class(ExportCapture)
        _capture["engine"] = ExportCapture
    engine = scene.render.engine
    for key in ("result", "error"):
        _capture.pop(key, None)
    _capture["kwargs"] = export_kwargs
    try:
        scene.render.engine = CAPTURE_ENGINE
        with bpy.context.temp_override(scene=scene):
            bpy.ops.render.render(write_still=False)
    finally:
        scene.render.engine = engine
        _capture.pop("kwargs", None)
    if "error" in _capture:
        raise _capture.pop("error")
    if "result" not in _capture:
        raise RuntimeError(f"the capturing render engine was not run on scene {scene.name!r}")
    return _capture.pop("result")
