"""Estimate render time: the operator in the Sampling panel and ``python -m mcrt_addon estimate``.

Both export the scene as F12 would (full frame, render border), render a short pilot on the same
kind of workers a render uses (worker processes, else threads in Blender) and predict the time to
reach the noise target (the panel's, or 1 % when it is off) with engine/rendering/estimate.py.
With the panel's noise target off the render F12 makes is uniform, so the pilot and the prediction
are too (adaptive sampling only works with a noise target).

The operator is modal: the scene is exported when it starts, the pilot renders on a thread while
a timer updates the progress bar and the status bar, and Esc (or right click) cancels it.
"""
import threading

import bpy

from . import bridge, worker_python

DEFAULT_TARGET = 0.01


def prepare_estimate(scene, depsgraph, target=None, log=None):
    """Export `scene` as it would render now; (estimate arguments, keyword arguments, whether the
    panel's noise target is off) for run_estimate.  Must run on Blender's main thread."""
    from .render_engine import border_rect, resolve_accelerator, start_worker_pool
    from .export import export_scene
    log = log or (lambda *a: None)
    settings = scene.tncg15.to_settings(bridge.settings_class())
    no_noise_target = target is None and not settings.noise_target > 0
    if no_noise_target:
        settings.adaptive = False              # F12 renders every pixel alike without a noise target
    target = target or (settings.noise_target if settings.noise_target > 0 else DEFAULT_TARGET)
    pct = scene.render.resolution_percentage / 100.0
    width, height = int(scene.render.resolution_x * pct), int(scene.render.resolution_y * pct)
    exported = export_scene(depsgraph, resolution=(width, height), camera=scene.camera,
                            crop=border_rect(scene.render, width, height))
    python, _ = worker_python.worker_python(worker_python.preferred_python())
    if python is not None:
        pool = start_worker_pool(python, settings, log=log)
    else:                                   # threads in Blender's process
        pool = None
        settings.accelerator, _ = resolve_accelerator(settings.accelerator)
    return (exported.scene, settings, target), dict(pool=pool, log=log), no_noise_target


def run_estimate(prepared, pilot_samples=64, on_progress=None, should_cancel=None):
    """The prediction dict of engine/rendering/estimate.py for prepare_estimate's result; any
    thread.  A cancelled pilot raises RuntimeError."""
    (scene, settings, target), kwargs, no_noise_target = prepared
    estimate = bridge.module("rendering.estimate").estimate
    result = estimate(scene, settings, target, bridge.render_function(), pilot_samples=pilot_samples,
                      on_progress=on_progress, should_cancel=should_cancel, **kwargs)
    result["no_noise_target"] = no_noise_target
    return result


def estimate_scene(scene, depsgraph, target=None, pilot_samples=64, log=None):
    """The prediction dict of engine/rendering/estimate.py for `scene` as it would render now."""
    return run_estimate(prepare_estimate(scene, depsgraph, target, log), pilot_samples)


def first_line(exc):
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


class EstimateJob:
    """The pilot on a thread: progress (0..1), the result or the error, and a cancel flag."""

    def __init__(self, prepared, pilot_samples=64):
        self.fraction, self.message = 0.0, "starting"
        self.result = self.error = None
        self.cancel_requested = False
        self.thread = threading.Thread(target=self._run, args=(prepared, pilot_samples), daemon=True)

    def start(self):
        self.thread.start()
        return self

    def _progress(self, fraction, message):
        self.fraction, self.message = float(fraction), message

    def _run(self, prepared, pilot_samples):
        try:
            self.result = run_estimate(prepared, pilot_samples, self._progress, lambda: self.cancel_requested)
        except Exception as exc:          # noqa: BLE001 - reported by the operator
            self.error = exc

    @property
    def done(self):
        return not self.thread.is_alive()


class TNCG15_OT_estimate_render_time(bpy.types.Operator):
    """Render a short pilot and predict the time to reach the noise target (1 % when it is off).
    Esc cancels"""
    bl_idname = "tncg15.estimate_render_time"
    bl_label = "Estimate Render Time"

    job = None
    timer = None

    def invoke(self, context, event):
        try:
            prepared = prepare_estimate(context.scene, context.evaluated_depsgraph_get())
        except Exception as exc:          # noqa: BLE001 - shown to the user as one line
            self.report({"ERROR"}, f"TNCG15 MC: estimate failed: {first_line(exc)}")
            return {"CANCELLED"}
        self.job = EstimateJob(prepared).start()
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self.timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        self._status(context, "Estimating render time: starting (Esc to cancel)")
        return {"RUNNING_MODAL"}

    def execute(self, context):             # from a script: blocking, no progress
        try:
            result = estimate_scene(context.scene, context.evaluated_depsgraph_get())
        except Exception as exc:          # noqa: BLE001 - shown to the user as one line
            self.report({"ERROR"}, f"TNCG15 MC: estimate failed: {first_line(exc)}")
            return {"CANCELLED"}
        return self._finish(context, result)

    def modal(self, context, event):
        job = self.job
        if event.type in {"ESC", "RIGHTMOUSE"} and event.value == "PRESS":
            job.cancel_requested = True
            self._status(context, "Estimating render time: cancelling")
        if event.type != "TIMER" and not job.done:
            return {"PASS_THROUGH"}
        if not job.done:
            context.window_manager.progress_update(int(job.fraction * 100))
            self._status(context, f"Estimating render time: pilot {job.message} (Esc to cancel)")
            return {"RUNNING_MODAL"}
        self._end(context)
        if job.cancel_requested:
            self.report({"INFO"}, "TNCG15 MC: estimate cancelled")
            return {"CANCELLED"}
        if job.error is not None:
            self.report({"ERROR"}, f"TNCG15 MC: estimate failed: {first_line(job.error)}")
            return {"CANCELLED"}
        return self._finish(context, job.result)

    def cancel(self, context):            # Blender ends the operator (file load, quit)
        if self.job is not None:
            self.job.cancel_requested = True
        self._end(context)

    def _finish(self, context, result):
        text = bridge.module("rendering.estimate").describe(result)
        context.scene.tncg15.estimate_text = text
        self.report({"INFO"}, f"TNCG15 MC: {text}")
        return {"FINISHED"}

    def _status(self, context, text):
        workspace = getattr(context, "workspace", None)
        if workspace is not None:
            workspace.status_text_set(text)

    def _end(self, context):
        wm = context.window_manager
        if self.timer is not None:
            wm.event_timer_remove(self.timer)
            self.timer = None
        wm.progress_end()
        self._status(context, None)


classes = (TNCG15_OT_estimate_render_time,)

register, unregister = bpy.utils.register_classes_factory(classes)
