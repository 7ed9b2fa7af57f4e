"""Exporter: the Principled BSDF v2's coat, sheen, alpha and emission sockets -> engine/scene/model.py
Principled (mcrt_addon/export/microfacet_nodes.py principled_layers), and the warnings naming material
and socket for what is still not modelled (Coat Normal, thin film, subsurface)."""
import bpy
import pytest

from tests.addon.test_export_materials import export, named, only, plate, shader

pytestmark = pytest.mark.skipif(bpy.app.version < (4, 0, 0), reason="Principled v2 is 4.0+")


def test_coat_and_sheen_sockets(scene, ms):
    plate(ms, scene, "P", ms.node_material("Lacquer", "ShaderNodeBsdfPrincipled", **{
        "Coat Weight": 0.8, "Coat Roughness": 0.1, "Coat IOR": 1.6, "Coat Tint": (1.0, 0.7, 0.4, 1),
        "Sheen Weight": 0.5, "Sheen Roughness": 0.3, "Sheen Tint": (0.9, 0.8, 1.0, 1)}))
    res = export()
    p = only(res, "Lacquer").principled
    assert (p.coat_weight, p.coat_roughness, p.coat_ior) == pytest.approx((0.8, 0.1, 1.6))
    assert p.coat_tint == pytest.approx((1.0, 0.7, 0.4)) and p.sheen_tint == pytest.approx((0.9, 0.8, 1.0))
    assert (p.sheen_weight, p.sheen_roughness, p.alpha) == pytest.approx((0.5, 0.3, 1.0))
    assert res.warnings == []


def test_alpha_is_the_layer_and_scales_the_emission(scene, ms):
    plate(ms, scene, "P", ms.node_material("Veil", "ShaderNodeBsdfPrincipled", **{
        "Alpha": 0.25, "Emission Color": (1.0, 0.5, 0.25, 1), "Emission Strength": 4.0}))
    res = export()
    m = only(res, "Veil")
    assert m.kind == "principled" and m.principled.alpha == pytest.approx(0.25)
    assert m.emission == pytest.approx((1.0, 0.5, 0.25))               # colour x strength x alpha, as Cycles
    assert named(res, "Veil", "input 'Alpha' 0.25: rays pass straight through"), res.warnings


def test_emission_under_a_coat_is_warned(scene, ms):
    plate(ms, scene, "P", ms.node_material("Glow", "ShaderNodeBsdfPrincipled", **{
        "Coat Weight": 1.0, "Emission Strength": 2.0}))
    res = export()
    assert only(res, "Glow").emission == pytest.approx((2.0, 2.0, 2.0))
    assert named(res, "Glow", "the emission is not darkened by the coat"), res.warnings


def test_coat_normal_linked_is_warned(scene, ms):
    mat = ms.node_material("Bumpy", "ShaderNodeBsdfPrincipled", **{"Coat Weight": 1.0})
    bump = mat.node_tree.nodes.new("ShaderNodeBump")
    mat.node_tree.links.new(bump.outputs["Normal"], shader(mat).inputs["Coat Normal"])
    plate(ms, scene, "P", mat)
    res = export()
    assert named(res, "Bumpy", "input 'Coat Normal' is linked"), res.warnings


@pytest.mark.parametrize("socket_name, value, text", [
    ("Subsurface Weight", 0.2, "is rendered as diffuse"), ("Thin Film Thickness", 250.0, "is not modelled")])
def test_what_is_not_modelled_names_material_and_socket(scene, ms, socket_name, value, text):
    plate(ms, scene, "P", ms.node_material("Layered", "ShaderNodeBsdfPrincipled", **{socket_name: value}))
    res = export()
    m = only(res, "Layered")
    assert m.kind == "principled"
    assert named(res, "Layered", f"input '{socket_name}' {value:g} {text}"), res.warnings
