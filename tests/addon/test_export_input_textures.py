"""Exporter: image textures on float inputs (Roughness, Metallic, Diffuse Roughness) and the tangents
of anisotropic materials (mcrt_addon/export/materials.py read_float, images.py float_image,
microfacet_nodes.py tangent_source, mesh.py corner_tangents), in bpy 5.0's node vocabulary."""
import math

import numpy as np
import pytest

from tests.addon.exporting import export as export_at


def export():
    return export_at((16, 16))


def shader(mat):
    out = mat.node_tree.get_output_node("CYCLES")
    return out.inputs["Surface"].links[0].from_node


def only(res, name):
    found = [m for m in res.scene.materials if m.name == name]
    assert len(found) == 1, [m.name for m in res.scene.materials]
    return found[0]


def named(res, material, text):
    return [w for w in res.warnings if f"Material '{material}'" in w and text in w]


def plate(ms, scene, name, material, uvs=None, rotation=(0.0, 0.0, 0.0), location=(0.0, 0.0, 0.0)):
    """A 1 m square in z = 0 centred on the origin; `uvs`: the one face's corner UVs (map "UVMap")."""
    ob = ms.mesh_object(scene, name, lambda bm: ms.quad(bm, [(-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0),
                                                              (-0.5, 0.5, 0)]),
                        material, rotation=rotation, location=location)
    if uvs is not None:
        ms.set_uvs(ob, {"UVMap": uvs})
    return ob


def halves(ms):
    return ms.packed_image("Halves", 2, 1, lambda x, y: (0.2, 0.8, 0.5) if x else (0.8, 0.2, 0.5), colorspace="Non-Color")


def textured(ms, name, kind, socket_name, image, channel=None, **kw):
    """A node material whose `socket_name` is fed by the image's Color, or through a Separate Color
    node's output `channel` (Red, Green, Blue)."""
    mat = ms.node_material(name, kind, **kw)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation = image, "Closest"
    if channel is None:
        links.new(tex.outputs["Color"], shader(mat).inputs[socket_name])
    else:
        sep = nodes.new("ShaderNodeSeparateColor")
        links.new(tex.outputs["Color"], sep.inputs["Color"])
        links.new(sep.outputs[channel], shader(mat).inputs[socket_name])
    return mat


SQUARE = [(0, 0), (1, 0), (1, 1), (0, 1)]


# ------------------------------------------------------------------------------------- float inputs
def test_a_roughness_texture_is_the_glossy_materials_input_texture(scene, ms):
    """Unlinked roughness 0 would be the mirror; a texture makes it glossy, read per hit."""
    plate(ms, scene, "P", textured(ms, "RoughMap", "ShaderNodeBsdfGlossy", "Roughness", halves(ms), Roughness=0.0),
          uvs=SQUARE)
    res = export()
    m = only(res, "RoughMap")
    assert m.kind == "glossy"
    slot = m.input_textures["roughness"]
    assert slot.channel == "luminance" and slot.interpolation == "Closest"
    assert res.scene.textures[slot.texture].colorspace == "Non-Color"
    assert res.scene.meshes[0].uvs is not None
    assert res.warnings == [], res.warnings
    res.scene.validate()


@pytest.mark.parametrize("channel, expected", [("Red", "r"), ("Green", "g"), ("Blue", "b")])
def test_principled_metallic_through_separate_color_reads_one_channel(scene, ms, channel, expected):
    plate(ms, scene, "P", textured(ms, "MetalMap", "ShaderNodeBsdfPrincipled", "Metallic", halves(ms), channel=channel),
          uvs=SQUARE)
    res = export()
    m = only(res, "MetalMap")
    assert m.kind == "principled" and m.input_textures["metallic"].channel == expected
    assert res.warnings == [], res.warnings


def test_principled_roughness_and_diffuse_roughness_textures(scene, ms):
    image = halves(ms)
    mat = textured(ms, "Both", "ShaderNodeBsdfPrincipled", "Roughness", image)
    tex = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage")
    mat.node_tree.links.new(tex.outputs["Color"], shader(mat).inputs["Diffuse Roughness"])
    plate(ms, scene, "P", mat, uvs=SQUARE)
    m = only(export(), "Both")
    assert sorted(m.input_textures) == ["diffuse_roughness", "roughness"]


@pytest.mark.parametrize("kind, row", [("ShaderNodeBsdfDiffuse", "rough diffuse"), ("ShaderNodeBsdfGlass", "rough glass")])
def test_diffuse_and_glass_roughness_textures_take_the_rough_rows(scene, ms, kind, row):
    from engine.materials.table import scatter_kind
    plate(ms, scene, "P", textured(ms, "Map", kind, "Roughness", halves(ms), Roughness=0.0), uvs=SQUARE)
    res = export()
    m = only(res, "Map")
    assert scatter_kind(m) == row
    assert list(m.input_textures) == ["diffuse_roughness" if kind.endswith("Diffuse") else "roughness"]


def test_other_links_to_a_float_input_are_named(scene, ms):
    """A node no kernel models (a Sky Texture in a material) is named; the input keeps its value."""
    mat = ms.node_material("Noisy", "ShaderNodeBsdfGlossy", Roughness=0.3)
    sky = mat.node_tree.nodes.new("ShaderNodeTexSky")
    sky.name = "Sky"
    mat.node_tree.links.new(sky.outputs["Color"], shader(mat).inputs["Roughness"])
    plate(ms, scene, "P", mat, uvs=SQUARE)
    res = export()
    m = only(res, "Noisy")
    assert m.input_textures == {} and not m.programs and m.roughness == pytest.approx(0.3)
    assert named(res, "Noisy", "input 'Roughness' is linked to 'Sky' (ShaderNodeTexSky), which is not modelled"), \
        res.warnings


def test_a_mix_leaf_keeps_its_roughness_texture(scene, ms):
    mat = textured(ms, "Leafy", "ShaderNodeBsdfGlossy", "Roughness", halves(ms))
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    glossy = shader(mat)
    diffuse, mix = nodes.new("ShaderNodeBsdfDiffuse"), nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.5
    links.new(diffuse.outputs[0], mix.inputs[1])
    links.new(glossy.outputs[0], mix.inputs[2])
    links.new(mix.outputs[0], mat.node_tree.get_output_node("CYCLES").inputs["Surface"])
    plate(ms, scene, "P", mat, uvs=SQUARE)
    res = export()
    m = only(res, "Leafy")
    assert m.kind == "mix"
    leaf = next(leaf.material for leaf in m.mix.leaves if leaf.material.kind == "glossy")
    assert "roughness" in leaf.input_textures
    assert res.scene.meshes[0].uvs is not None


# ------------------------------------------------------------------------------------------ tangents
def brushed(ms, name, tangent=None, uv_map=""):
    mat = ms.node_material(name, "ShaderNodeBsdfGlossy", Roughness=0.4, Anisotropy=0.8)
    if tangent is not None:
        node = mat.node_tree.nodes.new("ShaderNodeTangent")
        node.direction_type = tangent
        node.uv_map = uv_map
        mat.node_tree.links.new(node.outputs["Tangent"], shader(mat).inputs["Tangent"])
    return mat


def unit(rows):
    return rows / np.linalg.norm(rows, axis=-1, keepdims=True)


def test_the_default_tangent_is_radial_about_the_objects_z(scene, ms):
    """Cycles' default (Geometry > Tangent): (-(y - c_y), x - c_x, 0) / its texture space, normal-transformed.
    Turned by 90 degrees about Z the radial field is the same in world space."""
    plate(ms, scene, "A", brushed(ms, "Radial"), location=(2.0, 0.0, 0.0))
    plate(ms, scene, "B", brushed(ms, "Radial"), location=(0.0, 2.0, 0.0), rotation=(0.0, 0.0, math.pi / 2))
    res = export()
    assert res.warnings == [], res.warnings
    assert not res.scene.spheres
    for mesh in res.scene.meshes:
        m = res.scene.materials[int(mesh.material_ids[0])]
        assert m.tangent_source == "radial"
        p = np.asarray(mesh.vertices)[np.asarray(mesh.triangles)]          # (T, 3, 3) corners, world
        centre = np.asarray(mesh.vertices).mean(axis=0)
        expected = np.stack([-(p[..., 1] - centre[1]), p[..., 0] - centre[0], np.zeros(p.shape[:2])], axis=-1)
        assert np.allclose(unit(np.asarray(mesh.tangents)), unit(expected), atol=1e-6)


def test_a_uv_map_tangent_follows_the_uvs(scene, ms):
    """Tangent node, UV Map: MikkTSpace tangents (dP/du): u along x -> +x; the map turned 90 degrees (u
    along y) -> +y.  Control: the radial default differs from both."""
    plate(ms, scene, "Along x", brushed(ms, "UV", "UV_MAP", "UVMap"), uvs=SQUARE)
    plate(ms, scene, "Along y", brushed(ms, "UV turned", "UV_MAP", ""), uvs=[(0, 1), (0, 0), (1, 0), (1, 1)],
          location=(0.0, 2.0, 0.0))
    res = export()
    assert res.warnings == [], res.warnings
    by_name = {mesh.name: mesh for mesh in res.scene.meshes}
    assert only(res, "UV").tangent_source == "uv" and only(res, "UV").tangent_uv_map == "UVMap"
    assert np.allclose(unit(np.asarray(by_name["Along x"].tangents)), (1, 0, 0), atol=1e-5)
    assert np.allclose(unit(np.asarray(by_name["Along y"].tangents)), (0, 1, 0), atol=1e-5)


def test_other_tangent_links_are_named_and_the_default_is_used(scene, ms):
    mat = brushed(ms, "Odd")
    geometry = mat.node_tree.nodes.new("ShaderNodeNewGeometry")
    mat.node_tree.links.new(geometry.outputs["Normal"], shader(mat).inputs["Tangent"])
    plate(ms, scene, "P", mat)
    res = export()
    assert only(res, "Odd").tangent_source == "radial"
    assert named(res, "Odd", "input 'Tangent' is linked to"), res.warnings


def test_an_anisotropic_ball_stays_a_mesh(scene, ms):
    ms.mesh_object(scene, "Ball", lambda bm: ms.uv_sphere(bm, 0.3), brushed(ms, "Ball"))
    res = export()
    assert not res.scene.spheres and res.scene.meshes[0].tangents is not None
