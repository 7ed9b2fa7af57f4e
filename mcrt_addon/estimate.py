"""Estimate render time: the operator in the Sampling panel and ``python -m mcrt_addon estimate``.

Both export the scene as F12 would (full frame, render border), render a short pilot on the same
kind of workers a render uses (worker processes, else threads in Blender) and predict the time to
reach the noise target (the panel's, or 1 % when it is off) with engine/rendering/estimate.py.
"""
import bpy

from . import bridge, worker_python

DEFAULT_TARGET = 0.01


def estimate_scene(scene, depsgraph, target=None, pilot_samples=64, log=None):
    """The prediction dict of engine/rendering/estimate.py for `scene` as it would render now."""
    from .render_engine import border_rect, resolve_accelerator, start_worker_pool
    from .export import export_scene
    log = log or (lambda *a: None)
    settings = scene.tncg15.to_settings(bridge.settings_class())
    target = target or (settings.noise_target if settings.noise_target > 0 else DEFAULT_TARGET)
    pct = scene.render.resolution_percentage / 100.0
    width, height = int(scene.render.resolution_x * pct), int(scene.render.resolution_y * pct)
    exported = export_scene(depsgraph, resolution=(width, height), camera=scene.camera,
                            crop=border_rect(scene.render, width, height))
    estimate = bridge.module("rendering.estimate").estimate
    python, _ = worker_python.worker_python(worker_python.preferred_python())
    if python is not None:
        pool = start_worker_pool(python, settings, log=log)
    else:                                   # threads in Blender's process
        pool = None
        settings.accelerator, _ = resolve_accelerator(settings.accelerator)
    return estimate(exported.scene, settings, target, bridge.render_function(), pilot_samples=pilot_samples,
                    pool=pool, log=log)


class TNCG15_OT_estimate_render_time(bpy.types.Operator):
    """Render a short pilot and predict the time to reach the noise target (1 % when it is off)"""
    bl_idname = "tncg15.estimate_render_time"
    bl_label = "Estimate Render Time"

    def execute(self, context):
        try:
            result = estimate_scene(context.scene, context.evaluated_depsgraph_get())
        except Exception as exc:          # noqa: BLE001 - shown to the user as one line
            self.report({"ERROR"}, f"TNCG15 MC: estimate failed: {str(exc).strip().splitlines()[0]}")
            return {"CANCELLED"}
        text = bridge.module("rendering.estimate").describe(result)
        context.scene.tncg15.estimate_text = text
        self.report({"INFO"}, f"TNCG15 MC: {text}")
        return {"FINISHED"}


classes = (TNCG15_OT_estimate_render_time,)

register, unregister = bpy.utils.register_classes_factory(classes)
