"""Exporter: microfacet and rough diffuse nodes -> the scene model's values (mcrt_addon/export/materials.py,
microfacet_nodes.py), in the running Blender's node vocabulary (bpy 5.0 here; tests/addon/test_blender34.py
runs Blender 3.4)."""
import math

import bpy
import pytest

from tests.addon.exporting import export as export_at


def export():
    return export_at((16, 16))


def plate(ms, scene, name, material, z=0.0, rotation=(0.0, 0.0, 0.0)):
    return ms.mesh_object(scene, name, lambda bm: ms.quad(bm, [(0, 0, z), (1, 0, z), (1, 1, z), (0, 1, z)]),
                          material, rotation=rotation)


def only(res, name):
    found = [m for m in res.scene.materials if m.name == name]
    assert len(found) == 1, [m.name for m in res.scene.materials]
    return found[0]


def shader(mat):
    out = mat.node_tree.get_output_node("CYCLES")
    return out.inputs["Surface"].links[0].from_node


def named(res, material, text):
    return [w for w in res.warnings if f"Material '{material}'" in w and text in w]


def test_scene_records_the_running_blenders_version(scene, ms):
    plate(ms, scene, "P", ms.diffuse("D", (0.5, 0.5, 0.5)))
    assert export().scene.cycles_version == tuple(bpy.app.version[:2])


# ----------------------------------------------------------------------------------------- glossy
def test_glossy_roughness_zero_stays_the_mirror(scene, ms):
    plate(ms, scene, "P", ms.node_material("G0", "ShaderNodeBsdfGlossy", Color=(0.9, 0.8, 0.7, 1), Roughness=0.0))
    res = export()
    m = only(res, "G0")
    assert m.kind == "mirror" and m.color == pytest.approx((0.9, 0.8, 0.7))
    assert res.warnings == []


@pytest.mark.parametrize("menu, distribution, multiscatter", [
    ("MULTI_GGX", "ggx", True), ("GGX", "ggx", False), ("BECKMANN", "beckmann", False)])
def test_rough_glossy_is_the_glossy_kind(scene, ms, menu, distribution, multiscatter):
    mat = ms.node_material("G", "ShaderNodeBsdfGlossy", Color=(0.9, 0.8, 0.7, 1), Roughness=0.3,
                           Rotation=0.125)
    shader(mat).distribution = menu
    plate(ms, scene, "P", mat)
    res = export()
    m = only(res, "G")
    assert m.kind == "glossy" and m.fresnel == "none" and m.color == pytest.approx((0.9, 0.8, 0.7))
    assert m.roughness == pytest.approx(0.3) and m.anisotropy == 0.0 and m.rotation == pytest.approx(0.125)
    assert (m.distribution, m.multiscatter) == (distribution, multiscatter)
    assert res.warnings == [], res.warnings
    m.validate()


def test_ashikhmin_shirley_is_named_and_rendered_as_ggx(scene, ms):
    mat = ms.node_material("AS", "ShaderNodeBsdfGlossy", Roughness=0.4)
    shader(mat).distribution = "ASHIKHMIN_SHIRLEY"
    plate(ms, scene, "P", mat)
    res = export()
    assert (only(res, "AS").distribution, only(res, "AS").multiscatter) == ("ggx", False)
    assert named(res, "AS", "ASHIKHMIN_SHIRLEY"), res.warnings


def test_anisotropic_glossy_takes_the_tangent_of_each_object(scene, ms):
    """Cycles' default tangent (radial about the object's Z) comes from the mesh's corner tangents
    (tests/addon/test_export_input_textures.py); the material's fallback tangent, for hits without
    one, is the object's local X axis: two objects turned differently get two tracer materials."""
    mat = ms.node_material("Brushed", "ShaderNodeBsdfGlossy", Roughness=0.4, Anisotropy=0.6)
    a = plate(ms, scene, "A", mat)
    b = plate(ms, scene, "B", mat, z=1.0, rotation=(0.0, 0.0, math.pi / 2))
    c = plate(ms, scene, "C", mat, z=2.0)
    res = export()
    found = [m for m in res.scene.materials if m.name == "Brushed"]
    assert len(found) == 2
    by_object = {mesh.name: res.scene.materials[int(mesh.material_ids[0])] for mesh in res.scene.meshes}
    assert by_object["A"] is by_object["C"]
    assert by_object["A"].tangent == pytest.approx((1, 0, 0)) and by_object["A"].anisotropy == pytest.approx(0.6)
    assert by_object["B"].tangent == pytest.approx((0, 1, 0), abs=1e-6)
    assert by_object["A"].tangent_source == "radial"
    assert all(mesh.tangents is not None for mesh in res.scene.meshes)
    assert res.warnings == [], res.warnings
    del a, b, c


def test_linked_tangent_node_is_read(scene, ms):
    """A Tangent node (radial about Z, its default) is the default's tangent; other links are named
    (tests/addon/test_export_input_textures.py)."""
    mat = ms.node_material("Linked", "ShaderNodeBsdfGlossy", Roughness=0.4, Anisotropy=-0.5)
    tangent = mat.node_tree.nodes.new("ShaderNodeTangent")
    mat.node_tree.links.new(tangent.outputs[0], shader(mat).inputs["Tangent"])
    plate(ms, scene, "P", mat)
    res = export()
    assert only(res, "Linked").anisotropy == pytest.approx(-0.5)
    assert only(res, "Linked").tangent_source == "radial" and res.warnings == [], res.warnings


def test_glossy_colour_texture_is_the_colour_slot(scene, ms):
    image = ms.packed_image("Stripes", 2, 1, lambda x, y: (0.2 + 0.6 * x, 0.5, 0.5))
    mat = ms.node_material("Tex", "ShaderNodeBsdfGlossy", Roughness=0.3)
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")      # (5.0's Glossy node is ShaderNodeBsdfAnisotropic)
    tex.image = image
    mat.node_tree.links.new(tex.outputs["Color"], shader(mat).inputs["Color"])
    plate(ms, scene, "P", mat)
    m = only(export(), "Tex")
    assert m.kind == "glossy" and m.color_texture is not None


def test_linked_roughness_is_named(scene, ms):
    mat = ms.node_material("RT", "ShaderNodeBsdfGlossy", Roughness=0.3)
    value = mat.node_tree.nodes.new("ShaderNodeValue")
    mat.node_tree.links.new(value.outputs[0], shader(mat).inputs["Roughness"])
    plate(ms, scene, "P", mat)
    res = export()
    # a Value node folds into the input (mcrt_addon/export/node_graph.py): Cycles' value, no warning
    assert only(res, "RT").roughness == pytest.approx(0.5)
    assert not named(res, "RT", "input 'Roughness' is linked"), res.warnings


# --------------------------------------------------------------------------------------- metallic
needs_metallic = pytest.mark.skipif(bpy.app.version < (4, 3, 0), reason="the Metallic BSDF is 4.3+")


@needs_metallic
@pytest.mark.parametrize("roughness", [0.0, 0.35])
def test_metallic_f82(scene, ms, roughness):
    mat = ms.node_material("Gold", "ShaderNodeBsdfMetallic", **{"Base Color": (0.9, 0.7, 0.3, 1),
                                                               "Edge Tint": (0.95, 0.8, 0.5, 1),
                                                               "Roughness": roughness})
    plate(ms, scene, "P", mat)
    res = export()
    m = only(res, "Gold")
    assert m.kind == "glossy" and m.fresnel == "f82" and m.roughness == pytest.approx(roughness)
    assert m.color == pytest.approx((0.9, 0.7, 0.3)) and m.edge_tint == pytest.approx((0.95, 0.8, 0.5))
    assert (m.distribution, m.multiscatter) == ("ggx", True)
    assert res.warnings == []
    m.validate()


@needs_metallic
def test_metallic_physical_conductor(scene, ms):
    mat = ms.node_material("Copper", "ShaderNodeBsdfMetallic", Roughness=0.2)
    node = shader(mat)
    node.fresnel_type, node.distribution = "PHYSICAL_CONDUCTOR", "BECKMANN"   # makes IOR, Extinction available
    node.inputs["IOR"].default_value, node.inputs["Extinction"].default_value = (0.27, 0.68, 1.32), (3.61, 2.62, 2.29)
    plate(ms, scene, "P", mat)
    m = only(export(), "Copper")
    assert m.kind == "glossy" and m.fresnel == "conductor" and m.distribution == "beckmann"
    assert m.conductor_ior == pytest.approx((0.27, 0.68, 1.32)) and m.conductor_k == pytest.approx((3.61, 2.62, 2.29))
    assert max(m.color) > 0         # scatters (the colour itself is not used by conductors)


@needs_metallic
def test_metallic_thin_film_is_named(scene, ms):
    plate(ms, scene, "P", ms.node_material("Film", "ShaderNodeBsdfMetallic", **{"Thin Film Thickness": 300.0}))
    assert named(export(), "Film", "input 'Thin Film Thickness' 300 is not modelled")


# ---------------------------------------------------------------------------------------- diffuse
@pytest.mark.parametrize("roughness", [0.0, 0.6])
def test_diffuse_roughness(scene, ms, roughness):
    plate(ms, scene, "P", ms.node_material("Rough", "ShaderNodeBsdfDiffuse", Roughness=roughness))
    res = export()
    m = only(res, "Rough")
    assert m.kind == "diffuse" and m.diffuse_roughness == pytest.approx(roughness)
    assert res.warnings == []


# -------------------------------------------------------------------------------------- principled
needs_v2 = pytest.mark.skipif(bpy.app.version < (4, 0, 0), reason="Principled v2 is 4.0+")


@needs_v2
@pytest.mark.parametrize("roughness", [0.0, 0.4])
def test_principled_v2_values(scene, ms, roughness):
    mat = ms.node_material("P", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.6, 0.5, 0.4, 1), "Metallic": 0.3, "Roughness": roughness, "IOR": 1.6,
        "Specular IOR Level": 0.7, "Specular Tint": (0.9, 1.0, 0.8, 1), "Anisotropic": 0.2,
        "Anisotropic Rotation": 0.25, "Diffuse Roughness": 0.5})
    shader(mat).distribution = "GGX"
    plate(ms, scene, "P", mat)
    res = export()
    m = only(res, "P")
    assert m.kind == "principled" and m.color == pytest.approx((0.6, 0.5, 0.4))
    assert m.roughness == pytest.approx(roughness) and m.ior == pytest.approx(1.6)
    assert (m.distribution, m.multiscatter) == ("ggx", False)
    assert m.anisotropy == pytest.approx(0.2) and m.rotation == pytest.approx(0.25)
    assert m.diffuse_roughness == pytest.approx(0.5)
    p = m.principled
    assert p.metallic == pytest.approx(0.3) and p.specular_ior_level == pytest.approx(0.7)
    assert p.specular_tint == pytest.approx((0.9, 1.0, 0.8))
    assert [w for w in res.warnings if "radial" not in w] == [], res.warnings


@needs_v2
def test_principled_default_cube(scene, ms):
    """Blender's default material: the Principled BSDF with all its defaults."""
    plate(ms, scene, "P", ms.node_material("Default", "ShaderNodeBsdfPrincipled"))
    res = export()
    m = only(res, "Default")
    assert m.kind == "principled" and m.color == pytest.approx((0.8, 0.8, 0.8)) and m.roughness == 0.5
    assert m.ior == pytest.approx(1.5) and m.principled == type(m.principled)()     # the dataclass defaults
    assert max(m.emission) == 0 and res.warnings == []


@needs_v2
def test_principled_base_colour_texture(scene, ms):
    image = ms.packed_image("Stripes", 2, 1, lambda x, y: (0.2 + 0.6 * x, 0.5, 0.5))
    plate(ms, scene, "P", ms.image_material("PTex", "ShaderNodeBsdfPrincipled", "Base Color", image))
    m = only(export(), "PTex")
    assert m.kind == "principled" and m.color_texture is not None


@needs_v2
@pytest.mark.parametrize("socket_name, value", [
    ("Thin Film Thickness", 250.0)])     # coat, sheen, alpha: test_export_principled_layers.py
def test_principled_unmodelled_inputs_name_material_and_socket(scene, ms, socket_name, value):
    plate(ms, scene, "P", ms.node_material("Layered", "ShaderNodeBsdfPrincipled", **{socket_name: value}))
    res = export()
    assert only(res, "Layered").kind == "principled"
    assert named(res, "Layered", f"node 'Principled BSDF': input '{socket_name}' {value:g} is not modelled"), \
        res.warnings


@needs_v2
def test_principled_emission_as_before(scene, ms):
    plate(ms, scene, "P", ms.principled("Lamp", (0, 0, 0), emission_rgb=(1.0, 0.8, 0.6), emission_strength=5.0))
    m = only(export(), "Lamp")
    assert m.kind == "principled" and m.emission == pytest.approx((5.0, 4.0, 3.0))


@needs_v2
@pytest.mark.parametrize("transmission, roughness", [(0.8, 0.0), (0.3, 0.4), (1.0, 0.25)])
def test_principled_transmission_is_the_principleds_glass_closure(scene, ms, transmission, roughness):
    """'Transmission Weight' stays on the principled kind (engine/materials/principled_glass.py), with
    the node's roughness and IOR and no warning (it was exported as smooth glass before)."""
    plate(ms, scene, "P", ms.principled("Glassy", (0.9, 1, 1), roughness=roughness, transmission=transmission, ior=1.45))
    res = export()
    m = only(res, "Glassy")
    assert m.kind == "principled" and m.ior == pytest.approx(1.45) and m.roughness == pytest.approx(roughness)
    assert m.principled.transmission_weight == pytest.approx(transmission) and m.multiscatter
    assert res.warnings == [], res.warnings


def test_distribution_menu_maps_to_the_tracers_distributions():
    """mcrt_addon/export/microfacet_nodes.py distribution(): Multiscatter GGX is GGX with energy
    compensation; Ashikhmin-Shirley is not modelled: GGX and one warning naming material and node."""
    from types import SimpleNamespace

    from mcrt_addon.export.microfacet_nodes import distribution
    warned = []
    table = SimpleNamespace(warn=lambda mat, node, text: warned.append((mat.name, node.name, text)))
    mat = SimpleNamespace(name="Brushed")
    for menu, expected in (("GGX", ("ggx", False)), ("MULTI_GGX", ("ggx", True)), ("BECKMANN", ("beckmann", False))):
        assert distribution(table, mat, SimpleNamespace(name="Glossy", distribution=menu)) == expected
    assert not warned
    assert distribution(table, mat, SimpleNamespace(name="Glossy", distribution="ASHIKHMIN_SHIRLEY")) == ("ggx", False)
    assert warned == [("Brushed", "Glossy", "distribution ASHIKHMIN_SHIRLEY is not modelled; rendered as GGX")]
