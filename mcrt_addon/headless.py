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
