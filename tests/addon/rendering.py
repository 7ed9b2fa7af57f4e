"""Render helpers for the add-on tests (in-process bpy 5.0)."""
import os
import sys
import tempfile

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
if REPO not in sys.path:
    sys.path.insert(0, REPO)

import bpy  # noqa: E402

import mcrt_addon  # noqa: E402
from mcrt_addon import bridge  # noqa: E402
from mcrt_addon import render_engine as engine_module  # noqa: E402
from mcrt_addon.headless import ensure_registered, export_as_rendered, set_exr_output  # noqa: E402
from mcrt_addon.reference import setup_cycles_reference  # noqa: E402
from imagecompare import run_seeds  # noqa: E402


REPORTS = []                                     # every render's RenderReport (mcrt_addon/render_engine.py)
if REPORTS.append not in engine_module.REPORT_LISTENERS:
    engine_module.REPORT_LISTENERS.append(REPORTS.append)


def last_report():
    """The RenderReport of the latest render (an empty one when none ran since forget_reports)."""
    return REPORTS[-1] if REPORTS else engine_module.RenderReport()


def forget_reports():
    REPORTS.clear()


def read_exr(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise IOError(buf.geterror())
    return np.asarray(buf.get_pixels(oiio.FLOAT))[..., :3]


def open_blend(path, resolution=None):
    ensure_registered(mcrt_addon)
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    scene = bpy.context.scene
    if resolution is not None:
        scene.render.resolution_x, scene.render.resolution_y = resolution
        scene.render.resolution_percentage = 100
    return scene


def render_operator(scene, path=None):
    """Render the current scene with its engine through bpy.ops.render.render; returns the image."""
    if path is None:
        fd, path = tempfile.mkstemp(suffix=".exr")
        os.close(fd)
    set_exr_output(scene, path)
    if os.path.exists(path):
        os.remove(path)
    bpy.ops.render.render(write_still=True)
    img = read_exr(path)
    os.remove(path)
    return img


def cycles_runs(blend, resolution, samples, max_depth, seeds):
    scene = open_blend(blend, resolution)
    out = []
    for seed in seeds:
        setup_cycles_reference(scene, samples=samples, max_depth=max_depth, seed=seed)
        out.append(render_operator(scene))
    return np.stack(out)


def export_blend(blend, resolution):
    """The file's scene as F12 exports it: the render depsgraph, which Cycles renders (the
    viewport's would take modifiers at their viewport settings, mcrt_addon/headless.py)."""
    scene = open_blend(blend, resolution)
    return export_as_rendered(scene, resolution=resolution)


def tncg15_runs(tracer_scene, samples, max_depth, seeds, fresnel="exact", threads=0, **extra):
    render = bridge.render_function()
    Settings = bridge.settings_class()
    out = []
    for seed in seeds:
        settings = Settings(samples=samples, max_depth=max_depth, seed=seed, fresnel=fresnel,
                            threads=threads, **extra)
        result = render(tracer_scene, settings, log=lambda *a: None)
        out.append(np.asarray(result.image, dtype=np.float64))
    return np.stack(out)


def to_png(image, path, scale=1):
    """Save a linear image as an sRGB PNG for eyeballing."""
    import OpenImageIO as oiio
    a = np.clip(np.asarray(image, dtype=np.float64), 0, 1)
    a = np.where(a <= 0.0031308, 12.92 * a, 1.055 * a ** (1 / 2.4) - 0.055)
    if scale > 1:
        a = np.repeat(np.repeat(a, scale, 0), scale, 1)
    buf = oiio.ImageBuf(oiio.ImageSpec(a.shape[1], a.shape[0], 3, oiio.UINT8))
    buf.set_pixels(oiio.ROI(), (a * 255 + 0.5).astype(np.uint8))
    buf.write(path)


# -- the agreement tests' method (tests/addon/test_agreement*.py) ------------------------------------
RES = (64, 64)       # every agreement scene at 64 x 64,
SPP = 32             # 32 samples per pixel,
DEPTH = 8            # max depth 8,
K = 4                # K independent seeds of each renderer
_references = {}


def cycles_reference(blend, name=None):
    """Cycles' K runs of a .blend with the agreement settings, made once per test session."""
    key = name or blend
    if key not in _references:
        _references[key] = cycles_runs(blend, RES, SPP, DEPTH, seeds=range(1, K + 1))
    return _references[key]


def tncg15_agreement_runs(scene, first_seed=1000):
    """TNCG15 MC's K runs of an exported scene with the agreement settings (exact Fresnel, as Cycles)."""
    return tncg15_runs(scene, SPP, DEPTH, seeds=run_seeds(first_seed, K), fresnel="exact")
