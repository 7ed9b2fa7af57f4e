"""The comparison harnesses export the depsgraph that F12 and Cycles render (mcrt_addon/headless.py
export_as_rendered), not the viewport's: a Subdivision Surface whose Render levels differ from its
viewport Levels (as the Ignis evaluation scene roughness.blend has: 1 in the viewport, 2 for
render) and objects hidden in only one of the two.  With the viewport depsgraph the harness
rendered a coarser sphere than Cycles and its near-mirror highlight moved (docs/materials.md
"Files made by others").  Control: the viewport export of the same scene differs."""
import bpy

from mcrt_addon.headless import export_as_rendered

import rendering

RESOLUTION = (16, 16)


def triangles(exported):
    return sum(len(m.triangles) for m in exported.scene.meshes)


def _scene():
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.0))
    subsurf = bpy.context.object.modifiers.new("Subdivision", "SUBSURF")
    subsurf.levels, subsurf.render_levels = 0, 2                  # 12 triangles in the viewport, 192 rendered
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(3.0, 0.0, 0.0))
    bpy.context.object.hide_viewport = True                       # rendered: 2 triangles more
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(-3.0, 0.0, 0.0))
    bpy.context.object.hide_render = True                         # not rendered
    bpy.ops.object.camera_add(location=(0.0, -8.0, 0.0), rotation=(1.5708, 0.0, 0.0))
    scene.camera = bpy.context.object
    bpy.ops.object.light_add(type="POINT", location=(0.0, -3.0, 3.0))
    scene.render.engine = "CYCLES"
    return scene


def test_export_as_rendered_takes_render_levels_and_render_visibility(addon):
    scene = _scene()
    assert triangles(export_as_rendered(scene, resolution=RESOLUTION)) == 192 + 2
    assert scene.render.engine == "CYCLES"                        # the scene's engine is restored
    # control: the viewport's depsgraph (what the harnesses exported before) sees another scene
    bpy.context.view_layer.update()
    from mcrt_addon.export import export_scene
    assert triangles(export_scene(bpy.context.evaluated_depsgraph_get(), resolution=RESOLUTION)) == 12 + 2


def test_agreement_harness_exports_as_rendered(addon, tmp_path):
    _scene()
    path = str(tmp_path / "levels.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    assert triangles(rendering.export_blend(path, RESOLUTION)) == 192 + 2
    from mcrt_addon import bench_estimators           # scripts/agree_real_files.py's export
    assert triangles(bench_estimators.export_tracer_scene(bpy.context.scene, RESOLUTION)) == 192 + 2
