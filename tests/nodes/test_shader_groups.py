"""Shader node groups in the material export (mcrt_addon/export/materials.py shader walk, bpy 5.0):
a Principled BSDF inside a group feeding the Surface exports exactly the Material the same nodes give
ungrouped (kinds, values, textures, programs; node names aside), with no warning, for two materials
using the group with different inputs, nested in another group (through a reroute and a muted Add
Shader) and behind a Mix Shader whose factor is a group input; the CONTROL: the group with one inner
link changed exports another material.  A muted BSDF on the Surface passes no shader (black, as
Cycles).  A group without its tree and one containing itself: one warning naming the material and the
node.  The world (mcrt_addon/export/world.py): a Background and Environment Texture inside a group
export the ungrouped world's Environment (CONTROL: another Mapping rotation)."""
import os
import sys

import bpy
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "sample_blends"))

import make_samples as ms  # noqa: E402

from mcrt_addon.export import export_scene  # noqa: E402
from tests.nodes import shader_group_graphs as sg  # noqa: E402
from tests.nodes.shader_group_graphs import canonical  # noqa: E402

RED = ((0.8, 0.3, 0.2), 4.0, 0.0)                  # (tint, scale, metallic) of the first user
BLUE = ((0.2, 0.5, 0.9), sg.value_node(9.0), 1.0)  # the second: its Scale linked from a Value node outside


def export():
    bpy.context.view_layer.update()
    return export_scene(bpy.context.evaluated_depsgraph_get(), resolution=(8, 8))


@pytest.fixture(scope="module")
def empty_scene():
    s = ms.reset()
    ms.camera(s)
    ms.black_world(s)
    ms.settings(s, (8, 8))
    return s


@pytest.fixture
def scene(empty_scene):
    """The module's scene (reset once: each reset costs ~0.4 s) without the meshes of earlier tests."""
    for ob in [ob for ob in bpy.data.objects if ob.type == "MESH"]:
        bpy.data.objects.remove(ob)
    return empty_scene


def place(scene, mats):
    for i, mat in enumerate(mats):
        x = 2.5 * i
        ob = ms.plane(scene, mat.name, [(x - 1, -1, 0), (x + 1, -1, 0), (x + 1, 1, 0), (x - 1, 1, 0)], mat)
        ob.data.uv_layers.new(name="UVMap")


def materials(result):
    return {m.name: m for m in result.scene.materials}


def test_grouped_principled_exports_like_the_ungrouped_one(scene):
    surface = sg.surface_group()
    nested = sg.wrapper_group(surface)
    changed = sg.changed_group()
    mats = [sg.plain_material("PlainRed", *RED), sg.plain_material("PlainBlue", *BLUE),
            sg.group_material("GroupRed", surface, *RED)[0], sg.group_material("GroupBlue", surface, *BLUE)[0],
            sg.group_material("NestedBlue", nested, *BLUE)[0], sg.group_material("ChangedRed", changed, *RED)[0]]
    place(scene, mats)
    result = export()
    assert result.warnings == [], result.warnings
    m = materials(result)
    assert m["GroupRed"].kind == "principled" and set(m["GroupRed"].programs) == {"color", "roughness"}
    assert canonical(m["GroupRed"]) == canonical(m["PlainRed"])
    assert canonical(m["GroupBlue"]) == canonical(m["PlainBlue"])
    assert canonical(m["NestedBlue"]) == canonical(m["PlainBlue"])
    assert canonical(m["GroupRed"]) != canonical(m["GroupBlue"])          # one group, two sets of inputs
    assert canonical(m["ChangedRed"]) != canonical(m["PlainRed"])         # control
    names = [n.name for n in m["NestedBlue"].programs["roughness"].nodes]
    assert any(name.startswith("Group/Group/") for name in names), names


def coat_material(name, fac, base_rgb):
    mat, nodes, links, out = ms.empty_material(name)
    group = nodes.new("ShaderNodeGroup")
    group.node_tree = bpy.data.node_groups.get("Coat") or sg.coat_group()
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = tuple(base_rgb) + (1.0,)
    links.new(diffuse.outputs[0], group.inputs["Base"])
    sg.feed(links, fac(nodes, links) if callable(fac) else fac, group.inputs["Fac"])
    links.new(group.outputs["Shader"], out.inputs["Surface"])
    return mat


def plain_coat(name, fac, base_rgb):
    mat, nodes, links, out = ms.empty_material(name)
    mix = nodes.new("ShaderNodeMixShader")
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = tuple(base_rgb) + (1.0,)
    glossy = nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Roughness"].default_value = 0.3
    sg.feed(links, fac(nodes, links) if callable(fac) else fac, mix.inputs["Fac"])
    links.new(diffuse.outputs[0], mix.inputs[1])
    links.new(glossy.outputs[0], mix.inputs[2])
    links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def noise_fac(nodes, links):
    return nodes.new("ShaderNodeTexNoise").outputs["Fac"]


def test_mix_shader_inside_a_group_with_its_factor_from_a_group_input(scene):
    mats = [plain_coat("PlainConst", 0.3, (0.7, 0.6, 0.2)), coat_material("CoatConst", 0.3, (0.7, 0.6, 0.2)),
            plain_coat("PlainNoise", noise_fac, (0.1, 0.6, 0.2)), coat_material("CoatNoise", noise_fac, (0.1, 0.6, 0.2)),
            coat_material("CoatOther", 0.7, (0.7, 0.6, 0.2))]
    muted, nodes, links, out = ms.empty_material("Muted")       # a muted BSDF passes no shader: black, as
    lamp = nodes.new("ShaderNodeEmission")                       # Cycles renders it (measured in 5.0)
    lamp.mute = True
    links.new(lamp.outputs[0], out.inputs["Surface"])
    place(scene, mats + [muted])
    result = export()
    assert result.warnings == [], result.warnings
    m = materials(result)
    assert canonical(m["CoatConst"]) == canonical(m["PlainConst"])
    assert m["CoatNoise"].kind == "mix" and canonical(m["CoatNoise"]) == canonical(m["PlainNoise"])
    assert canonical(m["CoatOther"]) != canonical(m["CoatConst"])          # control: another factor
    assert m["Muted"].emission == (0.0, 0.0, 0.0) and m["Muted"].color == (0.0, 0.0, 0.0)


class _Sock:
    def __init__(self, name, source=None):
        self.identifier = self.name = name
        self.type, self.bl_idname = "SHADER", "NodeSocketShader"
        self.links = [] if source is None else [_Link(*source)]
        self.is_linked = bool(self.links)


class _Link:
    def __init__(self, node, sock):
        self.from_node, self.from_socket, self.is_muted, self.is_valid = node, sock, False, True


class _Node:
    def __init__(self, bl_idname, name, inputs=(), outputs=(), node_tree=None):
        self.bl_idname, self.name, self.bl_label, self.mute = bl_idname, name, bl_idname, False
        self.inputs, self.outputs, self.node_tree, self.internal_links = list(inputs), list(outputs), node_tree, []
        self.is_active_output = True

    def as_pointer(self):
        return id(self)


class _Tree:
    def __init__(self, name, nodes=()):
        self.name, self.nodes = name, list(nodes)


def _surface(group):
    """(material, warnings) of a material whose Surface is linked from `group`'s first output (stand-ins
    for bpy nodes: a group's tree is missing only in a file whose library is, and Blender refuses a
    group inside itself)."""
    from engine.scene import model
    from mcrt_addon.export.materials import MaterialTable
    from mcrt_addon.export.images import ImageTable
    from engine.scene import textures
    warnings = []
    table = MaterialTable(model, warnings, ImageTable(textures, warnings))
    surface = _Sock("Surface", source=(group, group.outputs[0]))
    return table.shader(_Tree("Mat"), *table.shader_source(_Tree("Mat"), surface)), warnings


def test_a_shader_group_without_its_tree_or_inside_itself_is_named_once():
    material, warnings = _surface(_Node("ShaderNodeGroup", "Lost", outputs=[_Sock("Shader")]))
    assert len(warnings) == 1 and "Material 'Mat', node 'Lost'" in warnings[0] and "without a node tree" in warnings[0]
    assert material.kind == "diffuse" and material.color == (0.0, 0.0, 0.0)      # no closure, as unlinked
    tree = _Tree("Loop")
    outer = _Node("ShaderNodeGroup", "Outer", outputs=[_Sock("Shader")], node_tree=tree)
    inner = _Node("ShaderNodeGroup", "Inner", outputs=[_Sock("Shader")], node_tree=tree)
    tree.nodes = [inner, _Node("NodeGroupOutput", "Group Output", [_Sock("Shader", source=(inner, inner.outputs[0]))])]
    material, warnings = _surface(outer)
    assert len(warnings) == 1 and "node 'Inner'" in warnings[0] and "contains itself" in warnings[0], warnings


def world_nodes(name, grouped, strength=2.5, rotation=0.5):
    """A world: Background(Color = Environment Texture(Mapping(Generated), rotated about Z), Strength);
    grouped: the Background and its texture inside a group whose inputs are the Vector (the Mapping,
    outside) and the Strength (its value), feeding the World Output through a reroute."""
    world = bpy.data.worlds.new(name)
    nodes, links = world.node_tree.nodes, world.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    out = nodes.new("ShaderNodeOutputWorld")
    coords = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, rotation)
    links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    if grouped:
        tree, gin, gout = sg.new_group(f"{name}Sky", [("Vector", "VECTOR"), ("Strength", "VALUE")],
                                       [("Background", "SHADER")])
        inner_nodes, inner_links, vector, power = tree.nodes, tree.links, gin.outputs["Vector"], gin.outputs["Strength"]
    else:
        inner_nodes, inner_links, vector, power = nodes, links, mapping.outputs["Vector"], strength
    env = inner_nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.get("Sky") or bpy.data.images.new("Sky", 8, 4, float_buffer=True)
    inner_links.new(vector, env.inputs["Vector"])
    background = inner_nodes.new("ShaderNodeBackground")
    inner_links.new(env.outputs["Color"], background.inputs["Color"])
    sg.feed(inner_links, power, background.inputs["Strength"])
    if not grouped:
        links.new(background.outputs[0], out.inputs["Surface"])
        return world
    inner_links.new(background.outputs[0], gout.inputs["Background"])
    group = nodes.new("ShaderNodeGroup")
    group.node_tree = tree
    links.new(mapping.outputs["Vector"], group.inputs["Vector"])
    group.inputs["Strength"].default_value = strength
    reroute = nodes.new("NodeReroute")
    links.new(group.outputs[0], reroute.inputs[0])
    links.new(reroute.outputs[0], out.inputs["Surface"])
    return world


def test_world_background_and_environment_inside_a_group_export_as_ungrouped(scene):
    from engine.scene import model, textures
    from mcrt_addon.export.images import ImageTable
    from mcrt_addon.export.world import export_world
    results = {}
    for name, grouped, rotation in (("Plain", False, 0.5), ("Grouped", True, 0.5), ("Turned", True, 0.9)):
        warnings = []
        colour, env = export_world(world_nodes(name, grouped, rotation=rotation), warnings,
                                   ImageTable(textures, warnings), model.Environment)
        assert warnings == [] and env is not None, warnings
        results[name] = canonical((colour, env))
    assert results["Grouped"] == results["Plain"]
    assert results["Turned"] != results["Plain"]                     # control: another Mapping rotation
    assert results["Grouped"][1]["strength"] == 2.5                  # the group node's Strength value
