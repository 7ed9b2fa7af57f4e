"""Export speed benchmark (prints figures; not a timed test).

Builds a grid mesh of about N triangles (and a second scene with many instances of one mesh) in an
empty file and times ``export_scene`` on the evaluated depsgraph.
"""
import math
import time

import numpy as np


def grid_mesh(name, n_triangles):
    """A flat grid with about n_triangles triangles, built with foreach_set (fast)."""
    import bpy
    q = max(1, int(math.sqrt(n_triangles / 2)))
    nv = (q + 1) ** 2
    x, y = np.meshgrid(np.linspace(-1, 1, q + 1), np.linspace(-1, 1, q + 1))
    co = np.column_stack([x.ravel(), y.ravel(), 0.05 * np.sin(7 * x.ravel()) * np.cos(5 * y.ravel())])
    i, j = np.meshgrid(np.arange(q), np.arange(q))
    v0 = (j * (q + 1) + i).ravel()
    quads = np.column_stack([v0, v0 + 1, v0 + q + 2, v0 + q + 1]).astype(np.int32)
    me = bpy.data.meshes.new(name)
    me.vertices.add(nv)
    me.vertices.foreach_set("co", co.astype(np.float32).ravel())
    me.loops.add(quads.size)
    me.loops.foreach_set("vertex_index", quads.ravel())
    me.polygons.add(len(quads))
    me.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    if hasattr(me.polygons[0], "loop_total") and not hasattr(me, "corner_normals"):
        me.polygons.foreach_set("loop_total", np.full(len(quads), 4, np.int32))   # Blender < 4.0
    me.update()
    me.validate()
    return me


def _camera(bpy, scene):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.location = (0, -4, 3)
    cam.rotation_euler = (math.radians(55), 0, 0)
    scene.camera = cam


def bench_export(n_triangles=1_000_000, n_instances=100):
    import bpy
    import mcrt_addon
    from mcrt_addon.headless import ensure_registered
    from mcrt_addon.export import export_scene
    from mcrt_addon.export.mesh import mesh_arrays

    ensure_registered(mcrt_addon)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    _camera(bpy, scene)
    t0 = time.perf_counter()
    me = grid_mesh("BenchGrid", n_triangles)
    ob = bpy.data.objects.new("BenchGrid", me)
    scene.collection.objects.link(ob)
    t_build = time.perf_counter() - t0
    depsgraph = bpy.context.evaluated_depsgraph_get()
    t0 = time.perf_counter()
    v, t, m = mesh_arrays(ob.evaluated_get(depsgraph).data)
    t_arrays = time.perf_counter() - t0
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        result = export_scene(depsgraph, resolution=(64, 64))
        times.append(time.perf_counter() - t0)
    tris = sum(len(mesh.triangles) for mesh in result.scene.meshes)
    print(f"mesh build (not timed as export): {t_build:.2f} s")
    print(f"single mesh: {tris:,} triangles, {len(v):,} vertices")
    print(f"  foreach_get arrays (first call, incl. triangulation): {t_arrays:.3f} s")
    print(f"  export_scene: best {min(times):.3f} s, all {', '.join(f'{x:.3f}' for x in times)} s "
          f"-> {tris / min(times) / 1e6:.2f} M triangles/s  [{'PASS' if min(times) < 2 else 'FAIL'} < 2 s]")

    # the same mesh shaded smooth: split normals read too (one foreach_get)
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    me.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        result = export_scene(depsgraph, resolution=(64, 64))
        times.append(time.perf_counter() - t0)
    smooth = sum(m.normals is not None for m in result.scene.meshes)
    print(f"  smooth-shaded ({smooth} mesh with corner normals): export_scene best {min(times):.3f} s, "
          f"all {', '.join(f'{x:.3f}' for x in times)} s [{'PASS' if min(times) < 2 else 'FAIL'} < 2 s]")
    me.polygons.foreach_set("use_smooth", np.zeros(len(me.polygons), dtype=bool))   # flat again
    me.update()
    textured_export(bpy, export_scene, depsgraph_of=lambda: bpy.context.evaluated_depsgraph_get(), me=me)

    # instancing: one 10k-triangle mesh used by n_instances objects (linked duplicates)
    bpy.data.objects.remove(ob)
    small = grid_mesh("BenchSmall", 10_000)
    for k in range(n_instances):
        inst = bpy.data.objects.new(f"Inst{k}", small)
        inst.location = (k % 10 * 2.5, k // 10 * 2.5, 0)
        scene.collection.objects.link(inst)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    t0 = time.perf_counter()
    result = export_scene(depsgraph, resolution=(64, 64))
    dt = time.perf_counter() - t0
    tris = sum(len(mesh.triangles) for mesh in result.scene.meshes)
    print(f"instances: {n_instances} objects sharing one mesh, {tris:,} triangles in total: {dt:.3f} s "
          f"(mesh arrays read {result.info['meshes_shared']} time(s))")
    return 0


def textured_export(bpy, export_scene, depsgraph_of, me):
    """The same mesh with a UV map and an Image Texture on its base colour: the exporter then
    reads the corner UVs too (foreach_get on the UV layer and loop_triangles' loops)."""
    layer = me.uv_layers.new(name="UVMap")
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    corner_vertex = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", corner_vertex)
    uv = (0.5 * co.reshape(-1, 3)[corner_vertex, :2] + 0.5).astype(np.float32).ravel()
    if hasattr(layer, "uv"):
        layer.uv.foreach_set("vector", uv)
    else:
        layer.data.foreach_set("uv", uv)
    mat = bpy.data.materials.new("Bench texture")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nodes = mat.node_tree.nodes
    shader = next(n for n in nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.new("Bench image", 256, 256)
    mat.node_tree.links.new(tex.outputs["Color"], shader.inputs["Base Color"])
    me.materials.append(mat)
    depsgraph = depsgraph_of()
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        result = export_scene(depsgraph, resolution=(64, 64))
        times.append(time.perf_counter() - t0)
    mesh = next(m for m in result.scene.meshes if m.uvs is not None)
    print(f"textured: {len(mesh.triangles):,} triangles with corner UVs {mesh.uvs.shape}, "
          f"{len(result.scene.textures)} image: export_scene best {min(times):.3f} s, all "
          f"{', '.join(f'{x:.3f}' for x in times)} s  [{'PASS' if min(times) < 2 else 'FAIL'} < 2 s]")
    me.materials.clear()
