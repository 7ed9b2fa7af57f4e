"""The current Blender scene through the exporter, for the export tests."""
import bpy

from mcrt_addon.export import export_scene


def export(resolution=(32, 32), **kw):
    """mcrt_addon/export/__init__.py export_scene on the evaluated depsgraph of the current scene."""
    bpy.context.view_layer.update()
    return export_scene(bpy.context.evaluated_depsgraph_get(), resolution=resolution, **kw)
