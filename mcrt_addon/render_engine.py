"""The RenderEngine: export the evaluated depsgraph, render it in worker processes, stream tiles
into Blender.

The tracer runs in worker processes (engine/pools/processes.py) of a Python chosen by
worker_python.py, through the tracer's one entry point (engine/api.py render with a pool from
make_pool; in the built add-on the tracer package is `tracer`, bridge.py):
Blender's own process only exports the scene and writes tiles, so Embree works even in Blender 3.4
(whose Embree 3 clashes with embreex in one process), Esc stops within a bounce, and a worker that
crashes is reported by name while Blender carries on.  When no worker Python exists at all the
tracer runs on threads in Blender's process, and the stats line says so.

Errors reach the user through ``self.report({'ERROR'}, ...)`` (and ``error_set``), never as a
traceback or a silent black image.  The user's data is only read.  Each render's outcome is a
RenderReport on the engine instance, handed to REPORT_LISTENERS (the command-line renderer, tests).
"""
import contextlib
import time
import traceback
from dataclasses import dataclass, field

import bpy

from . import bridge, persistent, viewport, warm, worker_python
from . import passes as addon_passes

# Stop requests besides Esc: callables polled with test_break() (the command line's SIGINT/SIGTERM).
STOP_REQUESTS = []
PREVIEW_SAMPLES = 16                # spp of material / world previews at most
# Callables given the RenderReport of every render that finishes (see capture_reports).
REPORT_LISTENERS = []


@dataclass
class RenderReport:
    """What one render did: its error or warnings, the tracer's stats, the export summary."""
    error: str = None
    warnings: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)
    cancelled: bool = False
    export: dict = None
    resolution: tuple = None
    crop: tuple = None
    wall_seconds: float = None
    passes: list = field(default_factory=list)     # Blender pass names written at the end
    stats_lines: list = field(default_factory=list)  # every update_stats info line, in order
    summary: str = None                            # the last of them, also in the Info log
    partial: object = None                         # no worker left: the finished tiles' RenderResult


@contextlib.contextmanager
def capture_reports():
    """``with capture_reports() as reports: bpy.ops.render.render()`` -> reports[-1]."""
    reports = []
    REPORT_LISTENERS.append(reports.append)
    try:
        yield reports
    finally:
        REPORT_LISTENERS.remove(reports.append)


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
    """Tracer tile (h, w, 3), or (h, w, 4) with a transparent film's alpha, row 0 = top -> flat
    float32 RGBA, row 0 = bottom (Blender's order)."""
    import numpy as np
    h, w = pixels.shape[:2]
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :pixels.shape[-1]] = pixels[::-1]
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
        from .export.util import ExportError
        raise ExportError("Accelerator 'Embree' cannot run inside Blender "
                          f"{'.'.join(map(str, version[:2]))}: embreex clashes with Blender's own "
                          "Embree 3 library (the process would crash). Choose Auto, Octree or Brute Force")
    return name, None


def blender_prints_stats(version=None, binary=None):
    """Whether Blender itself prints every update_stats line in the background: the blender
    binary up to 4.x writes "Fra:1 Mem:... | <line>" to stdout for each (render_pipeline.cc
    stats_background); from 5.0 on it logs them only at the "render" log's INFO level, and the
    bpy module (binary_path "") does not print them, so there the engine prints its own."""
    version = tuple(bpy.app.version) if version is None else tuple(version)
    binary = bpy.app.binary_path if binary is None else binary
    return bool(binary) and version < (5, 0, 0)


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
    bl_use_preview = True                   # material / world previews: few samples (PREVIEW_SAMPLES)
    bl_use_shading_nodes_custom = False     # read Cycles' shader nodes
    bl_use_postprocess = True
    bl_use_eevee_viewport = True            # Material Preview in the viewport uses EEVEE

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)   # required from Blender 4.4 on; harmless on 3.4

    def __del__(self):
        viewport.free(self)                 # leaving Rendered mode: stop the viewport's workers

    # -- the 3D viewport's Rendered mode (mcrt_addon/viewport.py) ------------------------------
    def view_update(self, context, depsgraph):
        viewport.view_update(self, context, depsgraph)

    def view_draw(self, context, depsgraph):
        viewport.view_draw(self, context, depsgraph)

    def update_render_passes(self, scene=None, renderlayer=None):
        """Combined and the enabled passes (mcrt_addon/passes.py), as Render Layers sockets."""
        addon_passes.register_passes(self, scene, renderlayer)

    # ------------------------------------------------------------------------------------------
    def render(self, depsgraph):
        self.last = RenderReport()
        self.tiles_written = 0
        try:
            self._render(depsgraph)
        except Exception as exc:                     # noqa: BLE001 - shown to the user, traceback to console
            message = self._readable(exc)
            if message is None:
                traceback.print_exc()
                message = f"TNCG15 MC internal error: {type(exc).__name__}: {exc}"
            if message != "cancelled":
                self._fail(message)
                self.last.partial = getattr(exc, "result", None) if self.tiles_written else None
        finally:
            if self.last.cancelled and not self.tiles_written:
                self._blank_result()
            for listener in list(REPORT_LISTENERS):
                listener(self.last)

    def _blank_result(self):
        """A render cancelled before its first tile still hands Blender a (black) result: without
        one, bpy 5.0 crashes writing the still (render.render(write_still=True))."""
        try:
            result = self.begin_result(0, 0, int(self.resolution_x), int(self.resolution_y))
            self.end_result(result)
        except (RuntimeError, ReferenceError):
            pass

    def _readable(self, exc):
        """The message of an error the user can act on, "cancelled", or None (a bug: traceback)."""
        if isinstance(exc, ImportError):
            return str(exc)
        try:
            from .export import ExportCancelled
            from .export.util import ExportError
        except ImportError:
            return None
        if isinstance(exc, ExportCancelled):
            self.last.cancelled = True
            return "cancelled"
        if isinstance(exc, ExportError):
            return str(exc)
        for module, name in (("core.errors", "SceneError"), ("pools.processes", "WorkerError")):
            try:
                if isinstance(exc, getattr(bridge.module(module), name)):
                    return str(exc)
            except ImportError:
                pass
        return None

    def _cancel_requested(self):
        """Esc in the render window, or a stop request (polled by the tracer between batches, ~0.1 s)."""
        return self.test_break() or any(stop() for stop in STOP_REQUESTS)

    def _stats(self, info):
        """update_stats(info), the line kept in the RenderReport."""
        self.last.stats_lines.append(info)
        self.update_stats("", info)

    def _fail(self, message):
        self.last.error = message
        self.report({"ERROR"}, message)
        try:
            self.error_set(message)
        except AttributeError:
            pass
        self._stats(f"TNCG15 MC | Error: {message}")

    def _render(self, depsgraph):
        if worker_python.NUMPY_PROBLEM:
            raise ImportError(worker_python.NUMPY_PROBLEM)
        import numpy as np
        from .export import export_scene

        t_start = time.perf_counter()
        scene = depsgraph.scene
        settings = scene.tncg15.to_settings(bridge.settings_class())
        wanted = addon_passes.enabled_passes(scene, depsgraph.view_layer)
        settings.passes = tuple(p for p in wanted if p != "noisy")
        if self.is_preview:                 # material preview: cheap, one worker, no passes, cancelled often
            settings.samples, settings.threads = min(settings.samples, PREVIEW_SAMPLES), 1
            wanted, settings.passes = (), ()
        cluster = None if self.is_preview else worker_python.render_cluster()
        pool, no_workers = (None, None) if cluster else self._start_workers(scene, settings)   # imports overlap the export
        try:
            width, height = int(self.resolution_x), int(self.resolution_y)
            crop = border_rect(scene.render, width, height)
            self._stats("TNCG15 MC | Exporting scene")
            camera = self.camera_override if self.camera_override is not None else scene.camera
            kept_meshes = None if self.is_preview else persistent.mesh_cache(scene, depsgraph)
            exported = export_scene(depsgraph, resolution=(width, height), camera=camera, crop=crop,
                                    test_break=self._cancel_requested, uv_pass="uv" in settings.passes,
                                    mesh_cache=kept_meshes)
            if abs(scene.render.pixel_aspect_x - scene.render.pixel_aspect_y) > 1e-6:
                exported.warnings.append("non-square pixel aspect is ignored")
            if pool is None and not cluster:
                settings.accelerator, note = resolve_accelerator(settings.accelerator)
                if note:
                    exported.warnings.append(note)
            settings.validate()
            warnings = list(exported.warnings) + list(exported.scene.validate())
            bridge.module("rendering.memory").check_memory(          # refused before allocating
                exported.scene, settings, pool="dask" if cluster else "workers" if pool is not None else "threads")
        except BaseException:
            if pool is not None:
                pool.close()
            raise
        out_w, out_h = exported.scene.resolution
        export_seconds = time.perf_counter() - t_start         # workers started, scene exported and checked
        self.last.export, self.last.resolution, self.last.crop = exported.info, (out_w, out_h), crop

        n_bad = [0]
        first_tile = []

        def on_tile(x0, y0, x1, y1, pixels):
            if not first_tile:
                first_tile.append(time.perf_counter() - t_start)
            # tracer rows count from the top; Blender's result rows from the bottom
            flat, bad = to_rgba_bottom_up(np.asarray(pixels, dtype=np.float32))
            n_bad[0] += bad
            self.tiles_written += 1
            result = self.begin_result(x0, out_h - y1, x1 - x0, y1 - y0)
            try:
                write_rect(result.layers[0].passes["Combined"], flat)
            finally:
                self.end_result(result)

        printed = [None]                 # when the last progress line went to the terminal
        echoes = blender_prints_stats()

        def on_progress(fraction, message):
            fraction = min(max(float(fraction), 0.0), 1.0)
            self.update_progress(fraction)
            line = stats_line(message)      # "Sample n/N · Remaining mm:ss · est. error x %"
            self._stats(line)
            # In the background nobody sees the stats: a progress line on the terminal, at most one
            # a second, unless Blender prints each stats line itself (blender_prints_stats).
            now = time.perf_counter()
            if bpy.app.background and not echoes and (printed[0] is None or now - printed[0] >= 1.0
                                                       or fraction >= 1.0):
                printed[0] = now
                print(f"{fraction * 100:5.1f}% {line}", flush=True)

        def log(*args):
            print(*args)

        self._stats("TNCG15 MC | Rendering")
        if cluster:
            pool = bridge.module("api").make_pool(f"dask:{cluster}", settings.resolved_threads(), log=log,
                                                  should_cancel=self._cancel_requested)
        elif pool is None:
            warnings.append(f"no render worker processes ({no_workers}): the tracer ran on threads inside Blender")
        result = bridge.render_function()(exported.scene, settings, pool=pool, on_tile=on_tile,
                                           should_cancel=self._cancel_requested, on_progress=on_progress, log=log)
        if not getattr(result, "cancelled", False) and wanted:
            self._write_passes(result, wanted, out_w, out_h, warnings,
                               bridge.module("film.passes").cryptomatte_metadata(
                                   exported.scene, wanted, depsgraph.view_layer.name))
        # the tracer validates the scene again and returns the same warnings: report each once
        warnings = list(dict.fromkeys(warnings + list(getattr(result, "warnings", []) or [])))
        if n_bad[0]:
            warnings.append(f"{n_bad[0]} pixels had NaN/infinite values and were set to black")
        stats = dict(getattr(result, "stats", {}) or {})
        stats["first_tile_seconds"] = first_tile[0] if first_tile else None
        stats["export_seconds"] = export_seconds
        if no_workers is not None:
            stats["parallelism"] = f"threads in Blender ({no_workers})"
        self.last.stats, self.last.warnings = stats, warnings
        self.last.cancelled = bool(getattr(result, "cancelled", False))
        self.last.wall_seconds = time.perf_counter() - t_start
        for w in warnings if not self.is_preview else ():      # the preview scene's own quirks
            self.report({"WARNING"}, w)
        self.update_progress(1.0)
        summary = stats_line(self._summary(stats, result), stats)
        self._stats(summary)                # the image editor's footer keeps the last stats line
        self.last.summary = summary
        if not self.is_preview:
            self.report({"INFO"}, summary)  # and the Info log the summary

    def _write_passes(self, result, wanted, width, height, warnings, metadata=()):
        """Denoise (in a process of the worker Python) when asked, then the whole frame: Combined
        and every pass Blender made a slot for."""
        import numpy as np
        passes = dict(getattr(result, "passes", {}) or {})
        image = np.asarray(result.image, dtype=np.float32)
        alpha = getattr(result, "alpha", None)          # a transparent film's (Combined is premultiplied)
        if "noisy" in wanted:
            self._stats("TNCG15 MC | Denoising")
            python = worker_python.worker_python(worker_python.preferred_python())[0]
            t0 = time.perf_counter()
            try:
                if python is None:
                    raise RuntimeError("no worker Python to run it in")
                denoised = bridge.module("film.denoise").denoise_in_subprocess(
                    python, image, passes.get("albedo"), passes.get("normal"), worker_python.extra_paths())
            except Exception as exc:                 # noqa: BLE001 - the render stays, undenoised
                warnings.append(f"Denoise skipped: {exc}")
            else:
                passes["noisy"], image = image, denoised
                result.stats["denoised"] = True
                result.stats["denoise_seconds"] = time.perf_counter() - t0
        if alpha is not None:
            image = np.concatenate([image, np.asarray(alpha, dtype=np.float32)[..., None]], axis=-1)
        self.last.passes = addon_passes.write_frame(self, width, height, image, passes, metadata)

    def _start_workers(self, scene, settings):
        """The worker pool (started, not yet given the scene), or (None, why) without a worker Python:
        with Persistent Data the one the last render left (mcrt_addon/persistent.py), else the
        viewport workers started ahead when they fit (mcrt_addon/warm.py)."""
        python, why = worker_python.worker_python(worker_python.preferred_python())
        if python is None:
            if worker_python.preferred_python():
                raise bridge.module("pools.processes").WorkerError(f"TNCG15 MC: {why}")
            return None, why
        kept = None if self.is_preview else persistent.render_pool(
            scene, python, settings.resolved_threads(), worker_python.extra_paths())
        if kept is None and not self.is_preview:        # the viewport workers started ahead (warm.py)
            kept = warm.render_pool(python, settings.resolved_threads(), worker_python.extra_paths())
        return kept or start_worker_pool(python, settings), None

    @staticmethod
    def _summary(stats, result):
        if getattr(result, "cancelled", False):
            return "Cancelled"
        spp = stats.get("samples_per_pixel")
        done = (f"{spp['mean']:.0f} of {stats.get('samples', '?')} samples (stopped by {stats['stopped_by']})"
                if isinstance(spp, dict) and "stopped_by" in stats else f"{stats.get('samples', '?')} samples")
        parts = [done, f"{stats.get('accelerator', '?')}",
                 str(stats.get("parallelism", ""))]
        seconds = stats.get("render_seconds")
        rays = stats.get("rays")
        if seconds and isinstance(rays, dict) and seconds > 0:
            total = sum(v for v in rays.values() if isinstance(v, (int, float)))
            parts.append(f"{total / seconds / 1e6:.2f} M rays/s")
        if seconds is not None:
            parts.append(f"{seconds:.2f} s")
        if isinstance(stats.get("estimated_rel_error"), float):
            parts.append(f"est. error {stats['estimated_rel_error'] * 100:.1f} %")
        return "Done: " + ", ".join(parts)


def start_worker_pool(python, settings, log=print):
    """The tracer's worker-process pool (engine/pools/spec.py "workers:PYTHON"): started now, given
    the scene when the render prepares it."""
    return bridge.module("api").make_pool(f"workers:{python}", settings.resolved_threads(), log=log,
                                          extra_paths=worker_python.extra_paths())


classes = (TNCG15RenderEngine,)

register, unregister = bpy.utils.register_classes_factory(classes)
