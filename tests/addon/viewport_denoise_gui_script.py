"""Run inside a Blender with a window (Debian's 3.4 under Xvfb; tests/addon/test_viewport_denoise_blender34.py):

    blender --factory-startup -p 0 0 W H --python viewport_denoise_gui_script.py -- ADDON_ZIP BLEND OUTDIR

Installs the add-on (the legacy zip, which bundles the denoiser), turns on Sampling > Viewport >
Denoise and Render > Denoise, switches the 3D viewport to Rendered through the camera, waits until
the view reached Max Samples and its denoised picture is drawn, screenshots the viewport and the
Render properties, turns Viewport > Denoise off (redrawing the viewport, as a click in the panel
does) and screenshots the noisy picture of the same samples.  What it measured goes to
OUTDIR/gui.json; the test reads the images.
"""
import json
import os
import sys
import time
import traceback

import bpy

SAMPLES = 4
HANG = 120.0                    # seconds: a wait that takes longer is reported as an error
zip_path, blend, outdir = sys.argv[sys.argv.index("--") + 1:][:3]
out = {}


def finish(error=None):
    out["error"] = error
    with open(os.path.join(outdir, "gui.json"), "w") as fh:
        json.dump(out, fh, indent=1, default=str)
    bpy.ops.wm.quit_blender()


bpy.ops.preferences.addon_install(filepath=zip_path)
bpy.ops.preferences.addon_enable(module="tncg15_mc")
bpy.ops.wm.open_mainfile(filepath=blend)
viewport = sys.modules["tncg15_mc.viewport"]


def view3d():
    win = bpy.context.window_manager.windows[0]
    area = max((a for a in win.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width * a.height)
    return win, area


def screenshot(name, area):
    win = bpy.context.window_manager.windows[0]
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(window=win, screen=win.screen, area=area, region=region):
        bpy.ops.screen.screenshot_area(filepath=os.path.join(outdir, name))


def wait_for(st, until, what):
    t = time.perf_counter()
    while not until():
        if st.workers is not None and st.workers.problem:
            raise RuntimeError(st.workers.problem)
        if time.perf_counter() - t > HANG:
            raise RuntimeError(f"{what}: not within {HANG:.0f} s ({st.workers.snapshot()[2:6]}, {st.workers.note()})")
        yield 0.05


def steps():
    sc = bpy.context.scene
    sc.render.engine = "TNCG15_MC"
    sc.tncg15.viewport_samples = SAMPLES
    sc.tncg15.use_preview_denoising = True
    sc.tncg15.use_denoising = True
    win, area = view3d()
    props = [a for a in win.screen.areas if a.type == "PROPERTIES"]
    if props:
        props[0].spaces.active.context = "RENDER"
    yield 0.5
    space = area.spaces.active
    space.overlay.show_overlays = False
    space.region_3d.view_perspective = "CAMERA"
    yield 0.2
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(window=win, screen=win.screen, area=area, region=region):
        bpy.ops.view3d.view_center_camera()
    space.shading.type = "RENDERED"
    t = time.perf_counter()
    while not [s for s in viewport.ACTIVE if not s.closed and s.workers is not None]:
        if time.perf_counter() - t > HANG:
            raise RuntimeError("the viewport never started")
        yield 0.05
    st = next(s for s in viewport.ACTIVE if not s.closed)
    w = st.workers
    yield from wait_for(st, lambda: (w.converged() and w.note() == "Denoised" and w.shown[1] >= SAMPLES
                                     and st.drawn_version == w.version), "the denoised picture at Max Samples")
    out["denoised_seconds"] = time.perf_counter() - t
    out["denoise_count"] = w.denoise_count
    out["resolution"] = st.resolution
    out["exports"] = st.exports
    yield 0.5
    screenshot("viewport_denoised.png", area)
    if props:
        screenshot("properties.png", props[0])
    sc.tncg15.use_preview_denoising = False
    area.tag_redraw()
    yield from wait_for(st, lambda: w.note() is None and st.drawn_version == w.version, "the noisy picture")
    yield 0.5
    screenshot("viewport_noisy.png", area)
    space.shading.type = "SOLID"
    yield 0.5


_steps = []


def timer():
    try:
        if not _steps:
            _steps.append(steps())
        return next(_steps[0])
    except StopIteration:
        finish()
    except Exception:                               # noqa: BLE001 - reported, and Blender quits
        finish(traceback.format_exc())
    return None


bpy.app.timers.register(timer, first_interval=1.0)
