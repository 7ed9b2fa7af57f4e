"""The exporter's node-graph compiler (mcrt_addon/export/node_graph.py) in bpy: programs for the BSDF
sockets, constants folded, unsupported nodes and node groups named once with the material, muted
nodes passed through, Image Texture nodes off the UV path compiled (straight UV ones stay slots)."""
import os
import sys

import bpy
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "addon"))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "sample_blends"))

import make_samples as ms  # noqa: E402

from mcrt_addon.export import export_scene  # noqa: E402
from mcrt_addon.export import node_graph  # noqa: E402


def export():
    bpy.context.view_layer.update()
    return export_scene(bpy.context.evaluated_depsgraph_get(), resolution=(16, 16))


@pytest.fixture
def scene():
    s = ms.reset()
    ms.camera(s)
    ms.black_world(s)
    ms.settings(s, (16, 16))
    return s


def material_on_plane(scene, build):
    mat, nodes, links, out = ms.empty_material("Graph")
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    build(nodes, links, bsdf)
    ms.plane(scene, "Plane", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], mat)
    return mat


def material(result):
    return next(m for m in result.scene.materials if m.name == "Graph")


def test_position_into_base_color_and_roughness_becomes_programs(scene):
    def build(nodes, links, bsdf):
        geo = nodes.new("ShaderNodeNewGeometry")
        mapping = nodes.new("ShaderNodeMapping")
        links.new(geo.outputs["Position"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], bsdf.inputs["Base Color"])
        links.new(geo.outputs["Backfacing"], bsdf.inputs["Roughness"])
    result = export()
    m = material_on_plane(scene, build) and material(export())
    assert sorted(m.programs) == ["color", "roughness"]
    color = m.programs["color"]
    assert [n.kind for n in color.nodes] == ["ShaderNodeNewGeometry", "ShaderNodeMapping"]
    assert color.nodes[0].props["_outputs"] == ["Position"] and color.type == "RGBA"
    assert m.programs["roughness"].type == "VALUE"
    del result


def test_constant_graph_folds_into_the_socket_value(scene):
    def build(nodes, links, bsdf):
        value = nodes.new("ShaderNodeValue")
        value.outputs[0].default_value = 0.25
        links.new(value.outputs[0], bsdf.inputs["Roughness"])
        rgb = nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = (0.1, 0.2, 0.3, 1.0)
        links.new(rgb.outputs[0], bsdf.inputs["Base Color"])
    material_on_plane(scene, build)
    m = material(export())
    assert not m.programs
    assert m.roughness == pytest.approx(0.25) and m.color == pytest.approx((0.1, 0.2, 0.3))


def test_unsupported_node_and_group_are_named_once_and_the_input_keeps_its_default(scene):
    def build(nodes, links, bsdf):
        bevel = nodes.new("ShaderNodeBevel")
        mapping = nodes.new("ShaderNodeMapping")
        mapping.inputs["Location"].default_value = (0.5, 0.5, 0.5)
        links.new(bevel.outputs["Normal"], mapping.inputs["Vector"])
        geo = nodes.new("ShaderNodeNewGeometry")
        links.new(geo.outputs["Position"], mapping.inputs["Scale"])
        links.new(mapping.outputs["Vector"], bsdf.inputs["Base Color"])
        group = nodes.new("ShaderNodeGroup")
        group.node_tree = bpy.data.node_groups.new("G", "ShaderNodeTree")
        if hasattr(group.node_tree, "interface"):
            group.node_tree.interface.new_socket("Out", in_out="OUTPUT", socket_type="NodeSocketFloat")
        else:
            group.node_tree.outputs.new("NodeSocketFloat", "Out")
        links.new(group.outputs[0], bsdf.inputs["Roughness"])
    material_on_plane(scene, build)
    result = export()
    bevel = [w for w in result.warnings if "'Bevel'" in w]
    groups = [w for w in result.warnings if "'Group'" in w]
    assert len(bevel) == 1 and "Material 'Graph'" in bevel[0] and "not supported" in bevel[0], result.warnings
    assert len(groups) == 1 and "ShaderNodeGroup" in groups[0], result.warnings
    m = material(result)
    mapping = next(n for n in m.programs["color"].nodes if n.kind == "ShaderNodeMapping")
    assert "Vector" not in mapping.inputs or not hasattr(mapping.inputs["Vector"], "node")
    assert "roughness" not in m.programs


def test_image_through_mapping_is_a_program_and_straight_uv_image_stays_a_slot(scene):
    img = bpy.data.images.new("Grid", 8, 8)

    def build(nodes, links, bsdf):
        coords = nodes.new("ShaderNodeTexCoord")
        mapping = nodes.new("ShaderNodeMapping")
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = img
        links.new(coords.outputs["Object"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
        links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
        straight = nodes.new("ShaderNodeTexImage")
        straight.image = img
        links.new(straight.outputs["Color"], bsdf.inputs["Emission Color"])
        bsdf.inputs["Emission Strength"].default_value = 1.0
    material_on_plane(scene, build)
    result = export()
    m = material(result)
    assert "color" in m.programs and m.color_texture is None
    tex = m.programs["color"].nodes[-1]
    assert tex.kind == "ShaderNodeTexImage" and tex.props["texture"] == 0
    assert m.emission_texture is not None and m.emission_texture.texture == 0
    assert not [w for w in result.warnings if "not modelled" in w or "not supported" in w], result.warnings
    assert ("ShaderNodeTexCoord", "Window") not in node_graph.UNMODELLED_OUTPUTS     # modelled: inputs.py


def test_muted_node_passes_its_input_through(scene):
    def build(nodes, links, bsdf):
        geo = nodes.new("ShaderNodeNewGeometry")
        mapping = nodes.new("ShaderNodeMapping")
        mapping.mute = True
        links.new(geo.outputs["Normal"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], bsdf.inputs["Base Color"])
    material_on_plane(scene, build)
    m = material(export())
    assert [n.kind for n in m.programs["color"].nodes] == ["ShaderNodeNewGeometry"]


def test_colour_attributes_reach_the_attribute_node(scene):
    import numpy as np
    from engine.geometry.scene_geometry import TRIANGLE
    from engine.nodes.context import SceneAttributes

    def build(nodes, links, bsdf):
        attr = nodes.new("ShaderNodeAttribute")
        attr.attribute_name = "Paint"
        links.new(attr.outputs["Color"], bsdf.inputs["Base Color"])
    material_on_plane(scene, build)
    me = bpy.data.objects["Plane"].data
    paint = me.color_attributes.new("Paint", "FLOAT_COLOR", "POINT")
    colours = [(1.0, 0.0, 0.0, 1.0), (0.0, 1.0, 0.0, 1.0), (0.0, 0.0, 1.0, 1.0), (1.0, 1.0, 1.0, 1.0)]
    for value, c in zip(paint.data, colours):
        value.color = c
    result = export()
    assert not result.warnings, result.warnings
    mesh = next(m for m in result.scene.meshes if m.name == "Plane")
    corners = mesh.colors["Paint"]
    assert corners.shape == (2, 3, 3)
    vertex_colour = {tuple(v): c[:3] for v, c in zip(mesh.vertices.round(6), colours)}
    for t, tri in enumerate(mesh.triangles):
        for k, v in enumerate(tri):
            assert tuple(corners[t, k]) == pytest.approx(vertex_colour[tuple(mesh.vertices[v].round(6))])
    scene_ = result.scene
    attrs = SceneAttributes(scene_, mesh.vertices[mesh.triangles], None)
    ctx = attrs.context(np.array([TRIANGLE]), np.array([0]), np.array([0.25]), np.array([0.25]), None, (5, 0), None,
                        TRIANGLE)
    expected = 0.5 * corners[0, 0] + 0.25 * corners[0, 1] + 0.25 * corners[0, 2]
    assert np.allclose(ctx.attr("color:Paint")[:, 0], expected)
