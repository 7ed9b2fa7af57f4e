"""Exporter: Add Shader and Mix Shader graphs -> one tracer material (mcrt_addon/export/shader_mix.py),
node -> material values, in the running Blender's vocabulary (bpy 5.0 here)."""
import bpy
import pytest

from tests.addon.exporting import export as export_at


def export():
    return export_at((16, 16))


def plate(ms, scene, material):
    ms.mesh_object(scene, "P", lambda bm: ms.quad(bm, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), material)


def only(res, name):
    found = [m for m in res.scene.materials if m.name == name]
    assert len(found) == 1, [m.name for m in res.scene.materials]
    return found[0]


def named(res, material, text):
    return [w for w in res.warnings if f"Material '{material}'" in w and text in w]


class Graph:
    """A material whose surface is built from nodes: ``graph.node(kind, **inputs)``, ``graph.add(a, b)``,
    ``graph.mix(fac, a, b)``, ``graph.output(node)``."""

    def __init__(self, name):
        self.mat = bpy.data.materials.new(name)
        self.tree = self.mat.node_tree
        for n in list(self.tree.nodes):
            self.tree.nodes.remove(n)
        self.out = self.tree.nodes.new("ShaderNodeOutputMaterial")

    def node(self, kind, **inputs):
        node = self.tree.nodes.new(kind)
        for key, value in inputs.items():
            node.inputs[key].default_value = value
        return node

    def _join(self, node, a, b):
        shaders = [s for s in node.inputs if s.bl_idname == "NodeSocketShader"]
        for sock, src in zip(shaders, (a, b)):
            if src is not None:
                self.tree.links.new(src.outputs[0], sock)
        return node

    def add(self, a, b):
        return self._join(self.tree.nodes.new("ShaderNodeAddShader"), a, b)

    def mix(self, fac, a, b):
        node = self.tree.nodes.new("ShaderNodeMixShader")
        node.inputs[0].default_value = fac
        return self._join(node, a, b)

    def output(self, node):
        self.tree.links.new(node.outputs[0], self.out.inputs["Surface"])
        return self.mat

    def diffuse(self, rgb, roughness=0.0):
        return self.node("ShaderNodeBsdfDiffuse", Color=(*rgb, 1), Roughness=roughness)

    def emission(self, rgb, strength):
        return self.node("ShaderNodeEmission", Color=(*rgb, 1), Strength=strength)

    def glossy(self, rgb, roughness):
        return self.node("ShaderNodeBsdfGlossy", Color=(*rgb, 1), Roughness=roughness)


# ------------------------------------------------------------------------------------- Add Shader
@pytest.mark.parametrize("emission_first", [False, True])
def test_diffuse_plus_emission_is_the_diffuse_material_emitting(scene, ms, emission_first):
    g = Graph("Lamp")
    d, e = g.diffuse((0.5, 0.6, 0.7)), g.emission((1.0, 0.8, 0.5), 4.0)
    plate(ms, scene, g.output(g.add(e, d) if emission_first else g.add(d, e)))
    res = export()
    m = only(res, "Lamp")
    assert m.kind == "diffuse" and m.color == pytest.approx((0.5, 0.6, 0.7))
    assert m.emission == pytest.approx((4.0, 3.2, 2.0))
    assert res.warnings == [], res.warnings
    m.validate()


def test_nested_add_shaders_sum_their_emission(scene, ms):
    g = Graph("Nested")
    inner = g.add(g.emission((1, 1, 1), 2.0), g.glossy((0.9, 0.9, 0.9), 0.3))
    plate(ms, scene, g.output(g.add(g.emission((1, 0, 0), 3.0), inner)))
    res = export()
    m = only(res, "Nested")
    assert m.kind == "glossy" and m.roughness == pytest.approx(0.3) and m.color == pytest.approx((0.9, 0.9, 0.9))
    assert m.emission == pytest.approx((5.0, 2.0, 2.0))
    assert res.warnings == [], res.warnings


def test_emission_alone_stays_a_black_emitter(scene, ms):
    g = Graph("E")
    plate(ms, scene, g.output(g.emission((1.0, 0.5, 0.25), 2.0)))
    m = only(export(), "E")
    assert m.kind == "diffuse" and m.color == (0.0, 0.0, 0.0) and m.emission == pytest.approx((2.0, 1.0, 0.5))


def test_add_with_an_unconnected_input_is_the_other_side(scene, ms):
    g = Graph("Half")
    plate(ms, scene, g.output(g.add(None, g.emission((1, 1, 1), 3.0))))
    m = only(export(), "Half")
    assert m.kind == "diffuse" and m.color == (0.0, 0.0, 0.0) and m.emission == pytest.approx((3.0, 3.0, 3.0))


def test_add_of_two_diffuse_adds_the_colours(scene, ms):
    g = Graph("Two")
    plate(ms, scene, g.output(g.add(g.diffuse((0.2, 0.3, 0.4)), g.diffuse((0.1, 0.1, 0.1)))))
    m = only(export(), "Two")
    assert m.kind == "diffuse" and m.color == pytest.approx((0.3, 0.4, 0.5))


def test_textured_emission_beside_a_bsdf_keeps_its_texture(scene, ms):
    image = ms.packed_image("Glow", 2, 1, lambda x, y: (0.2 + 0.6 * x, 0.5, 0.5))
    g = Graph("TexLamp")
    e = g.emission((1, 1, 1), 5.0)
    tex = g.tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    g.tree.links.new(tex.outputs["Color"], e.inputs["Color"])
    plate(ms, scene, g.output(g.mix(0.5, g.diffuse((0.5, 0.5, 0.5)), e)))
    res = export()
    m = only(res, "TexLamp")
    assert m.emission_texture is not None and m.emission_texture.scale == pytest.approx((2.5, 2.5, 2.5))
    assert m.color == pytest.approx((0.25, 0.25, 0.25)) and m.color_texture is None


# ------------------------------------------------------------------------------------- Mix Shader
@pytest.mark.parametrize("fac", [0.0, 0.25, 0.5, 1.0])
def test_mix_of_two_diffuse_blends_the_colours(scene, ms, fac):
    g = Graph("Mix")
    plate(ms, scene, g.output(g.mix(fac, g.diffuse((0.8, 0.2, 0.0)), g.diffuse((0.0, 0.4, 0.8)))))
    res = export()
    m = only(res, "Mix")
    expected = tuple((1 - fac) * a + fac * b for a, b in zip((0.8, 0.2, 0.0), (0.0, 0.4, 0.8)))
    assert m.kind == "diffuse" and m.color == pytest.approx(expected, abs=1e-6)
    assert res.warnings == [], res.warnings


def test_mix_of_two_glossy_of_one_roughness_blends_the_colours(scene, ms):
    g = Graph("Gloss")
    plate(ms, scene, g.output(g.mix(0.3, g.glossy((1.0, 0.0, 0.0), 0.4), g.glossy((0.0, 0.0, 1.0), 0.4))))
    m = only(export(), "Gloss")
    assert m.kind == "glossy" and m.roughness == pytest.approx(0.4)
    assert m.color == pytest.approx((0.7, 0.0, 0.3), abs=1e-6)


@pytest.mark.parametrize("fac, side", [(0.0, 0), (1.0, 1)])
def test_mix_factor_zero_or_one_is_that_side(scene, ms, fac, side):
    g = Graph("Pick")
    sides = (g.glossy((0.9, 0.8, 0.7), 0.3), g.node("ShaderNodeBsdfGlass", IOR=1.33))
    plate(ms, scene, g.output(g.mix(fac, *sides)))
    res = export()
    m = only(res, "Pick")
    assert m.kind == ("glossy", "glass")[side]
    assert res.warnings == [], res.warnings


def test_mix_with_an_emission_scales_both(scene, ms):
    g = Graph("Glow")
    plate(ms, scene, g.output(g.mix(0.25, g.diffuse((0.8, 0.8, 0.8)), g.emission((1.0, 0.5, 0.0), 8.0))))
    res = export()
    m = only(res, "Glow")
    assert m.kind == "diffuse" and m.color == pytest.approx((0.6, 0.6, 0.6))
    assert m.emission == pytest.approx((2.0, 1.0, 0.0))
    assert res.warnings == [], res.warnings


def test_mix_factor_is_clamped(scene, ms):
    g = Graph("Clamp")
    mix = g.mix(0.0, g.diffuse((0.8, 0.8, 0.8)), g.emission((1, 1, 1), 2.0))
    mix.inputs[0].default_value = 1.0        # the socket's range is [0, 1]: at most 1
    plate(ms, scene, g.output(mix))
    m = only(export(), "Clamp")
    assert m.color == (0.0, 0.0, 0.0) and m.emission == pytest.approx((2.0, 2.0, 2.0))


def test_a_factor_source_not_modelled_is_named_and_its_unlinked_value_used(scene, ms):
    g = Graph("Noise")
    mix = g.mix(0.5, g.diffuse((0.8, 0.0, 0.0)), g.diffuse((0.0, 0.0, 0.8)))
    noise = g.tree.nodes.new("ShaderNodeTexSky")          # no kernel models a Sky Texture in a material
    g.tree.links.new(noise.outputs[0], mix.inputs[0])
    plate(ms, scene, g.output(mix))
    res = export()
    assert only(res, "Noise").color == pytest.approx((0.4, 0.0, 0.4))
    assert [w for w in named(res, "Noise", "is linked") if f"node '{mix.name}'" in w and noise.name in w], res.warnings


def test_rough_diffuse_of_two_colours_is_not_blended_in_4_3(scene, ms):
    """Cycles 4.3+'s Oren-Nayar is not linear in its colour: no blend, a mix of the two closures."""
    g = Graph("RoughMix")
    plate(ms, scene, g.output(g.mix(0.5, g.diffuse((0.8, 0.8, 0.8), 0.5), g.diffuse((0.2, 0.2, 0.2), 0.5))))
    res = export()
    if bpy.app.version >= (4, 3, 0):
        m = only(res, "RoughMix")
        assert m.kind == "mix" and [leaf.material.color for leaf in m.mix.leaves] == [
            pytest.approx((0.8, 0.8, 0.8)), pytest.approx((0.2, 0.2, 0.2))]
        assert res.warnings == [], res.warnings
    else:
        assert only(res, "RoughMix").color == pytest.approx((0.5, 0.5, 0.5))


def test_mix_of_different_bsdfs_is_a_closure_list(scene, ms):
    g = Graph("DG")
    plate(ms, scene, g.output(g.mix(0.7, g.diffuse((0.8, 0.8, 0.8)), g.glossy((0.9, 0.9, 0.9), 0.2))))
    res = export()
    m = only(res, "DG")
    assert res.warnings == [], res.warnings
    assert m.kind == "mix" and [leaf.material.kind for leaf in m.mix.leaves] == ["diffuse", "glossy"]
    assert [[f.constant() for f in leaf.factors] for leaf in m.mix.leaves] == [[pytest.approx(0.3)],
                                                                                [pytest.approx(0.7)]]
    assert m.mix.leaves[1].material.roughness == pytest.approx(0.2)
    assert m.mix.leaves[0].material.name.startswith("DG: ")          # leaves named after their nodes
    m.validate()


def link(g, output, sock):
    g.tree.links.new(output, sock)


@pytest.mark.parametrize("source", ["fresnel", "facing", "layer fresnel"])
def test_fresnel_and_layer_weight_factors(scene, ms, source):
    g = Graph("Varnish")
    mix = g.mix(0.5, g.diffuse((0.8, 0.1, 0.1)), g.glossy((1.0, 1.0, 1.0), 0.1))
    if source == "fresnel":
        node = g.node("ShaderNodeFresnel", IOR=1.6)
        link(g, node.outputs["Fac"], mix.inputs[0])
    else:
        node = g.node("ShaderNodeLayerWeight", Blend=0.3)
        link(g, node.outputs["Facing" if source == "facing" else "Fresnel"], mix.inputs[0])
    plate(ms, scene, g.output(mix))
    res = export()
    m = only(res, "Varnish")
    assert res.warnings == [], res.warnings
    (d, gl) = m.mix.leaves
    assert [f.invert for f in d.factors] == [True] and [f.invert for f in gl.factors] == [False]
    f = gl.factors[0]
    assert f.node == node.name
    if source == "fresnel":
        assert f.kind == "fresnel" and f.ior == pytest.approx(1.6)
    else:
        assert f.kind == "layer_weight" and f.blend == pytest.approx(0.3)
        assert f.output == ("facing" if source == "facing" else "fresnel")
    m.validate()


def test_image_texture_factor_is_uv_mapped(scene, ms):
    image = ms.packed_image("Mask", 2, 1, lambda x, y: (x, x, x))
    g = Graph("Masked")
    mix = g.mix(0.5, g.diffuse((0.8, 0.8, 0.8)), g.node("ShaderNodeBsdfGlass", IOR=1.45))
    tex = g.tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    link(g, tex.outputs["Color"], mix.inputs[0])
    plate(ms, scene, g.output(mix))
    res = export()
    m = only(res, "Masked")
    factor = m.mix.leaves[1].factors[0]
    assert factor.kind == "texture" and res.scene.textures[factor.texture.texture].name == "Mask"
    assert factor.value == pytest.approx(0.5)                     # where a hit has no UV
    assert res.scene.meshes[0].uvs is not None                    # the mesh exports its UVs for it
    res.scene.validate()


def test_nested_mixes_flatten_with_multiplied_weights(scene, ms):
    g = Graph("Nest")
    lw = g.node("ShaderNodeLayerWeight", Blend=0.4)
    inner = g.mix(0.5, g.glossy((0.9, 0.9, 0.9), 0.3), g.node("ShaderNodeBsdfGlass", IOR=1.5))
    link(g, lw.outputs["Facing"], inner.inputs[0])
    plate(ms, scene, g.output(g.mix(0.25, g.diffuse((0.2, 0.4, 0.6)), inner)))
    m = only(export(), "Nest")
    kinds = [leaf.material.kind for leaf in m.mix.leaves]
    assert kinds == ["diffuse", "glossy", "glass"]
    weights = [[(f.kind, f.invert, f.constant() if f.is_constant else None) for f in leaf.factors]
               for leaf in m.mix.leaves]
    assert weights == [[("constant", False, pytest.approx(0.75))],
                       [("constant", False, pytest.approx(0.25)), ("layer_weight", True, None)],
                       [("constant", False, pytest.approx(0.25)), ("layer_weight", False, None)]]
    m.validate()


def test_add_of_different_bsdfs_sums_them_at_weight_one(scene, ms):
    g = Graph("Sum")
    plate(ms, scene, g.output(g.add(g.diffuse((0.5, 0.5, 0.5)), g.glossy((0.8, 0.8, 0.8), 0.4))))
    res = export()
    m = only(res, "Sum")
    assert m.kind == "mix" and [leaf.factors for leaf in m.mix.leaves] == [[], []]     # weights 1 + 1
    assert res.warnings == [], res.warnings


def test_emission_inside_a_mix_goes_to_the_mix_material(scene, ms):
    g = Graph("GlowMix")
    lamp = g.add(g.diffuse((0.5, 0.5, 0.5)), g.emission((1.0, 1.0, 1.0), 3.0))
    plate(ms, scene, g.output(g.mix(0.5, lamp, g.glossy((0.9, 0.9, 0.9), 0.3))))
    res = export()
    m = only(res, "GlowMix")
    assert m.kind == "mix" and m.emission == pytest.approx((1.5, 1.5, 1.5))
    assert all(leaf.material.emission == (0.0, 0.0, 0.0) for leaf in m.mix.leaves)
    assert res.warnings == [], res.warnings
    m.validate()


def test_emission_weighted_by_fresnel_is_named(scene, ms):
    g = Graph("Rim")
    mix = g.mix(0.5, g.diffuse((0.5, 0.5, 0.5)), g.emission((1.0, 1.0, 1.0), 4.0))
    fresnel = g.node("ShaderNodeFresnel", IOR=1.5)
    link(g, fresnel.outputs["Fac"], mix.inputs[0])
    plate(ms, scene, g.output(mix))
    res = export()
    m = only(res, "Rim")
    assert m.emission == pytest.approx((0.16, 0.16, 0.16))          # 4 x F0(1.5) = 4 x 0.04
    assert named(res, "Rim", "not modelled per hit"), res.warnings
    assert m.kind == "mix" and m.mix.leaves[0].factors[0].invert


def test_a_weighted_principled_keeps_its_weight(scene, ms):
    """A closure not linear in its colour at weight 0.5 is a one-leaf mix (Cycles scales the closure)."""
    g = Graph("HalfP")
    plate(ms, scene, g.output(g.mix(0.5, g.node("ShaderNodeBsdfPrincipled"), g.emission((1, 1, 1), 2.0))))
    res = export()
    m = only(res, "HalfP")
    assert m.kind == "mix" and len(m.mix.leaves) == 1 and m.mix.leaves[0].factors[0].constant() == 0.5
    assert m.emission == pytest.approx((1.0, 1.0, 1.0))
    assert not named(res, "HalfP", "not modelled"), res.warnings


def test_only_closures_linear_in_their_colour_are_blended():
    """mcrt_addon/export/shader_mix.py colour_is_weight: a Mix of two such closures is the closure
    of the mixed colour; the energy-preserving Oren-Nayar (4.3+) and a Fresnel-weighted glossy
    are not linear in their colour, so they are never blended."""
    from types import SimpleNamespace

    from engine.scene.model import DIFFUSE, GLASS, GLOSSY, MIRROR, REFRACTION, TRANSLUCENT, TRANSPARENT, Material
    from mcrt_addon.export.shader_mix import colour_is_weight
    kinds = dict(DIFFUSE=DIFFUSE, MIRROR=MIRROR, GLASS=GLASS, GLOSSY=GLOSSY, REFRACTION=REFRACTION,
                 TRANSPARENT=TRANSPARENT, TRANSLUCENT=TRANSLUCENT)
    new, old = SimpleNamespace(version=(5, 0), **kinds), SimpleNamespace(version=(3, 4), **kinds)
    assert colour_is_weight(new, Material("d", DIFFUSE)) and colour_is_weight(new, Material("m", MIRROR))
    assert colour_is_weight(new, Material("g", GLOSSY, fresnel="none"))
    assert colour_is_weight(new, Material("t", TRANSLUCENT)) and colour_is_weight(new, Material("r", GLASS, roughness=0.3))
    assert not colour_is_weight(new, Material("r", GLASS, roughness=0.3, distribution="multi_ggx"))
    assert not colour_is_weight(new, Material("g", GLOSSY, fresnel="dielectric"))
    rough = Material("r", DIFFUSE, diffuse_roughness=0.5)
    assert not colour_is_weight(new, rough) and colour_is_weight(old, rough)
