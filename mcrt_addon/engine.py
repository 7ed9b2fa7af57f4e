"""The RenderEngine: export the evaluated depsgraph, run the tracer, stream tiles into Blender.

Errors reach the user through ``self.report({'ERROR'}, ...)`` (and ``error_set``), never as a
traceback or a silent black image.  The user's data is only read.
"""
import math
import time
import traceback

import bpy
import numpy as np

from . import bridge
from .export import ExportCancelled, export_scene
from .export.util import ExportError

# Statistics of the most recent render in this process (read by the command-line renderer and tests).
LAST_RENDER = {}
# Stop requests besides Esc: callables polled with test_break() (the command line's SIGINT/SIGTERM).
STOP_REQUESTS = []


def border_rect(render, width, height):
    """Blender's border in full-frame pixels (x0, y0, x1, y1), y from the bottom, or None.

    Blender truncates border * resolution (render_initialize_from_main)."""
    if not render.use_border:
        return None
    x0, x1 = int(render.border_min_x * width), int(render.border_max_x * width)
    y0, y1 = int(render.border_min_y * height), int(render.border_max_y * height)
    if x1 <= x0 or y1 <= y0:
        return None
    if (x0, y0, x1, y1) == (0, 0, width, height):
        return None
    return x0, y0, x1, y1


def to_rgba_bottom_up(pixels):
    """Tracer tile (h, w, 3), row 0 = top -> flat float32 RGBA, row 0 = bottom (Blender's order)."""
    h, w = pixels.shape[:2]
    rgba = np.empty((h, w, 4), np.float32)
    rgba[..., :3] = pixels[::-1]
    rgba[..., 3] = 1.0
    bad = ~np.isfinite(rgba)
    if bad.any():
        rgba[bad] = 0.0
    return rgba.ravel(), int(bad.any(axis=-1).sum())


def write_rect(render_pass, flat_rgba):
    """RenderPass.rect accepts a flat buffer through foreach_set (2.83+, 3.4 and 5.0)."""
    try:
        render_pass.rect.foreach_set(flat_rgba)
    except (TypeError, AttributeError):
        render_pass.rect = flat_rgba.reshape(-1, 4)          # slow fallback


def resolve_accelerator(name, version=None):
    """Blender 3.x (Debian's 3.4 links the system's Embree 3 dynamically) cannot host embreex:
    embreex's Embree 4 calls bind to Blender's Embree 3 symbols and the process crashes.  There,
    'auto' means the tracer's octree and 'embree' is refused with an explanation."""
    version = tuple(bpy.app.version) if version is None else version
    if version >= (4, 0, 0):
        return name, None
    if name == "auto":
        return "octree", None
    if name == "embree":
        raise ExportError("Accelerator 'Embree' cannot run inside Blender "
                          f"{'.'.join(map(str, version[:2]))}: embreex clashes with Blender's own "
                          "Embree 3 library (the process would crash). Choose Auto, Octree or Brute Force")
    return name, None


def stats_line(message, stats=None):
    text = f"TNCG15 MC | {message}"
    if stats:
        effects = [k for k, v in stats.get("effects", {}).items() if v]
        if effects:
            text += " | effects: " + ", ".join(effects)
    return text


class TNCG15RenderEngine(bpy.types.RenderEngine):
    bl_idname = "TNCG15_MC"
    bl_label = "TNCG15 MC"
    bl_use_preview = False
    bl_use_shading_nodes_custom = False     # read Cycles' shader nodes
    bl_use_postprocess = True
    bl_use_eevee_viewport = True            # Material Preview in the viewport uses EEVEE

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)   # required from Blender 4.4 on; harmless on 3.4

    # ------------------------------------------------------------------------------------------
    def render(self, depsgraph):
        LAST_RENDER.clear()
        LAST_RENDER.update(error=None, warnings=[], stats={}, cancelled=False)
        try:
            self._render(depsgraph)
        except ExportCancelled:
            LAST_RENDER["cancelled"] = True
        except ExportError as exc:
            self._fail(str(exc))
        except ImportError as exc:
            self._fail(str(exc))
        except Exception as exc:                     # noqa: BLE001 - shown to the user, traceback to console
            scene_error = None
            try:
                scene_error = bridge.scene_module().SceneError
            except ImportError:
                pass
            if scene_error is not None and isinstance(exc, scene_error):
                self._fail(str(exc))
            else:
                traceback.print_exc()
                self._fail(f"TNCG15 MC internal error: {type(exc).__name__}: {exc}")

    def _cancel_requested(self):
        """Esc in the render window, or a stop request (polled by the tracer between batches, ~0.1 s)."""
        return self.test_break() or any(stop() for stop in STOP_REQUESTS)

    def _fail(self, message):
        LAST_RENDER["error"] = message
        self.report({"ERROR"}, message)
        try:
            self.error_set(message)
        except AttributeError:
            pass
        self.update_stats("", f"TNCG15 MC | Error: {message}")

    def _render(self, depsgraph):
        t_start = time.perf_counter()
        scene = depsgraph.scene
        width, height = int(self.resolution_x), int(self.resolution_y)
        crop = border_rect(scene.render, width, height)
        self.update_stats("", "TNCG15 MC | Exporting scene")
        camera = self.camera_override if self.camera_override is not None else scene.camera
        exported = export_scene(depsgraph, resolution=(width, height), camera=camera, crop=crop,
                                test_break=self._cancel_requested)
        if abs(scene.render.pixel_aspect_x - scene.render.pixel_aspect_y) > 1e-6:
            exported.warnings.append("non-square pixel aspect is ignored")
        settings = scene.tncg15.to_settings(bridge.settings_class())
        settings.accelerator, note = resolve_accelerator(settings.accelerator)
        if note:
            exported.warnings.append(note)
        settings.validate()
        warnings = list(exported.warnings) + list(exported.scene.validate())
        bridge.module("memory").check_memory(exported.scene, settings)     # refused before allocating
        render = bridge.render_function()
        out_w, out_h = exported.scene.resolution
        LAST_RENDER.update(export=exported.info, resolution=(out_w, out_h), crop=crop)

        n_bad = [0]

        def on_tile(x0, y0, x1, y1, pixels):
            # tracer rows count from the top; Blender's result rows from the bottom
            flat, bad = to_rgba_bottom_up(np.asarray(pixels, dtype=np.float32))
            n_bad[0] += bad
            result = self.begin_result(x0, out_h - y1, x1 - x0, y1 - y0)
            try:
                write_rect(result.layers[0].passes["Combined"], flat)
            finally:
                self.end_result(result)

        t_render = time.perf_counter()

        def on_progress(fraction, message):
            self.update_progress(min(max(float(fraction), 0.0), 1.0))
            self.update_stats("", stats_line(f"{message} | {settings.samples} spp | "
                                              f"{time.perf_counter() - t_render:.1f} s"))

        def log(*args):
            print(*args)

        self.update_stats("", "TNCG15 MC | Rendering")
        result = render(exported.scene, settings, on_tile=on_tile, should_cancel=self._cancel_requested,
                        on_progress=on_progress, log=log)
        # the tracer validates the scene again and returns the same warnings: report each once
        warnings = list(dict.fromkeys(warnings + list(getattr(result, "warnings", []) or [])))
        if n_bad[0]:
            warnings.append(f"{n_bad[0]} pixels had NaN/infinite values and were set to black")
        stats = dict(getattr(result, "stats", {}) or {})
        LAST_RENDER.update(stats=stats, warnings=warnings, cancelled=bool(getattr(result, "cancelled", False)),
                           wall_seconds=time.perf_counter() - t_start)
        for w in warnings:
            self.report({"WARNING"}, w)
        self.update_progress(1.0)
        self.update_stats("", stats_line(self._summary(stats, result), stats))

    @staticmethod
    def _summary(stats, result):
        if getattr(result, "cancelled", False):
            return "Cancelled"
        parts = [f"{stats.get('samples', '?')} samples"]
        seconds = stats.get("render_seconds")
        rays = stats.get("rays")
        if seconds and isinstance(rays, dict) and seconds > 0:
            total = sum(v for v in rays.values() if isinstance(v, (int, float)))
            parts.append(f"{total / seconds / 1e6:.2f} M rays/s")
        if seconds is not None:
            parts.append(f"{seconds:.2f} s")
        return "Done: " + ", ".join(parts)


classes = (TNCG15RenderEngine,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
