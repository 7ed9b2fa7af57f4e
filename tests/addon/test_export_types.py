"""Exporter (mcrt_addon/export/__init__.py): every evaluated geometry is taken once.  Blender 3.0+
lists a curve, text, metaball or NURBS surface object beside an instance holding its evaluated
mesh; both used to be exported (twice the triangles, "X (instanced by X)" in the names).  Triangle
counts are checked against Blender's evaluated meshes; geometry-nodes and particle instances keep
one copy per instance."""
import bpy
import pytest

from mcrt_addon.export import export_scene


def export(resolution=(16, 16)):
    bpy.context.view_layer.update()
    return export_scene(bpy.context.evaluated_depsgraph_get(), resolution=resolution)


def evaluated_triangles(ob):
    """Triangles of Blender's evaluated mesh of `ob` (what Cycles renders)."""
    evaluated = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
    me = evaluated.to_mesh()
    try:
        me.calc_loop_triangles()
        return len(me.loop_triangles)
    finally:
        evaluated.to_mesh_clear()


def add_curve():
    bpy.ops.curve.primitive_bezier_circle_add()
    bpy.context.object.data.bevel_depth = 0.1


def add_text():
    bpy.ops.object.text_add()
    bpy.context.object.data.body = "TNCG15"


def add_metaball():
    bpy.ops.object.metaball_add()


def add_surface():
    bpy.ops.surface.primitive_nurbs_surface_sphere_add()


KINDS = {"bevelled curve": add_curve, "text": add_text, "metaball": add_metaball, "NURBS surface": add_surface}


@pytest.fixture
def scene(empty_scene, make_samples_module):
    make_samples_module.camera(empty_scene)
    return empty_scene


@pytest.mark.parametrize("kind", list(KINDS))
def test_a_convertible_object_is_exported_once(scene, kind):
    KINDS[kind]()
    ob = bpy.context.object
    expected = evaluated_triangles(ob)
    result = export()
    assert expected > 0
    assert [m.name for m in result.scene.meshes] == [ob.name], [m.name for m in result.scene.meshes]
    assert result.info["triangles"] == expected and len(result.scene.meshes[0].triangles) == expected
    assert not [w for w in result.warnings if "instanced by" in w], result.warnings


def test_every_kind_together_and_a_mesh_beside_them(scene):
    expected = 0
    for add in KINDS.values():
        add()
        expected += evaluated_triangles(bpy.context.object)
    bpy.ops.mesh.primitive_cube_add(location=(5, 0, 0))
    result = export()
    assert result.info["triangles"] == expected + 12 and len(result.scene.meshes) == len(KINDS) + 1


def geometry_nodes_instances(ob, count):
    """A geometry-nodes modifier on `ob`: a cube instanced on `count` points of a line."""
    group = bpy.data.node_groups.new("Instances", "GeometryNodeTree")
    group.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    group.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = group.nodes, group.links
    out = nodes.new("NodeGroupOutput")
    line = nodes.new("GeometryNodeMeshLine")
    line.inputs["Count"].default_value = count
    points = nodes.new("GeometryNodeMeshToPoints")
    cube = nodes.new("GeometryNodeMeshCube")
    cube.inputs["Size"].default_value = (0.2, 0.2, 0.2)
    inst = nodes.new("GeometryNodeInstanceOnPoints")
    links.new(line.outputs["Mesh"], points.inputs["Mesh"])
    links.new(points.outputs["Points"], inst.inputs["Points"])
    links.new(cube.outputs["Mesh"], inst.inputs["Instance"])
    links.new(inst.outputs["Instances"], out.inputs["Geometry"])
    ob.modifiers.new("Instances", "NODES").node_group = group


def test_geometry_nodes_instances_are_one_copy_each(scene):
    bpy.ops.mesh.primitive_plane_add()
    geometry_nodes_instances(bpy.context.object, 5)
    result = export()
    assert result.info["triangles"] == 5 * 12 and len(result.scene.meshes) == 5


def test_a_text_instanced_by_geometry_nodes_is_one_copy_per_instance(scene):
    add_text()
    text = bpy.context.object
    per_copy = evaluated_triangles(text)
    text.hide_render = text.hide_viewport = True          # only its instances render
    bpy.ops.mesh.primitive_plane_add()
    group = bpy.data.node_groups.new("TextInstances", "GeometryNodeTree")
    group.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    group.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = group.nodes, group.links
    out, line, points = nodes.new("NodeGroupOutput"), nodes.new("GeometryNodeMeshLine"), nodes.new("GeometryNodeMeshToPoints")
    line.inputs["Count"].default_value = 3
    info, inst = nodes.new("GeometryNodeObjectInfo"), nodes.new("GeometryNodeInstanceOnPoints")
    info.inputs["Object"].default_value = text
    links.new(line.outputs["Mesh"], points.inputs["Mesh"])
    links.new(points.outputs["Points"], inst.inputs["Points"])
    links.new(info.outputs["Geometry"], inst.inputs["Instance"])
    links.new(inst.outputs["Instances"], out.inputs["Geometry"])
    bpy.context.object.modifiers.new("Texts", "NODES").node_group = group
    result = export()
    assert result.info["triangles"] == 3 * per_copy, (result.info, per_copy, [m.name for m in result.scene.meshes])


def test_particle_instances_are_one_copy_each(scene):
    bpy.ops.mesh.primitive_cube_add(location=(0, 0, 5), size=0.2)
    cube = bpy.context.object
    cube.hide_render = cube.hide_viewport = True          # only its instances render
    bpy.ops.mesh.primitive_plane_add(size=4)
    emitter = bpy.context.object
    emitter.modifiers.new("Particles", "PARTICLE_SYSTEM")
    settings = emitter.particle_systems[0].settings
    settings.count, settings.frame_start, settings.frame_end = 7, 1, 1
    settings.render_type, settings.instance_object = "OBJECT", cube
    settings.physics_type = "NO"
    emitter.show_instancer_for_render = emitter.show_instancer_for_viewport = False
    bpy.context.scene.frame_set(2)
    result = export()
    assert result.info["triangles"] == 7 * 12, (result.info, [m.name for m in result.scene.meshes])
    assert all("(instanced by Plane)" in m.name for m in result.scene.meshes)
