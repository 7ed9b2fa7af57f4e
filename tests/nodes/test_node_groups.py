"""Node groups in the exporter (mcrt_addon/export/node_graph.py, bpy 5.0): a Principled material whose
Base Color comes from a group exports without a warning and with the same program as the same graph
ungrouped (the control: a group whose inner link is changed gives another program), and what feeds
only an unused group input is not warned about; a group without a
node tree is named with the material; an unlinked group Vector into a texture keeps the texture's
implicit coordinates; a colour through a Float group socket is a float before 5.0 only."""
import os
import sys

import bpy
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "sample_blends"))

import make_samples as ms  # noqa: E402

from mcrt_addon.export import export_scene  # noqa: E402
from tests.nodes.group_graphs import compiled, group_node, new_group  # noqa: E402


def export():
    bpy.context.view_layer.update()
    return export_scene(bpy.context.evaluated_depsgraph_get(), resolution=(8, 8))


@pytest.fixture
def scene():
    s = ms.reset()
    ms.camera(s)
    ms.black_world(s)
    ms.settings(s, (8, 8))
    return s


def principled(name, build, scene):
    mat, nodes, links, out = ms.empty_material(name)
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    links.new(build(nodes, links), bsdf.inputs["Base Color"])
    ms.plane(scene, name, [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], mat)
    return mat


def checker_chain(tree_nodes, tree_links, vector, scale):
    """Mapping(vector) -> Checker -> Gamma: the graph both materials share; the Gamma output."""
    mapping = tree_nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (2.0, 3.0, 1.0)
    tree_links.new(vector, mapping.inputs["Vector"])
    checker = tree_nodes.new("ShaderNodeTexChecker")
    tree_links.new(mapping.outputs[0], checker.inputs["Vector"])
    tree_links.new(scale, checker.inputs["Scale"])
    gamma = tree_nodes.new("ShaderNodeGamma")
    tree_links.new(checker.outputs["Color"], gamma.inputs["Color"])
    return gamma.outputs[0]


def shape(program):
    """A program without node names: (kind, props, inputs) per node, and its output."""
    return [(n.kind, n.props, n.inputs) for n in program.nodes], program.output


def test_grouped_graph_exports_like_the_ungrouped_one(scene):
    def plain(nodes, links):
        coords = nodes.new("ShaderNodeTexCoord")
        value = nodes.new("ShaderNodeValue")
        value.outputs[0].default_value = 4.0
        math = nodes.new("ShaderNodeMath")                   # keeps the scale per hit-independent but linked
        math.operation = "ADD"
        links.new(value.outputs[0], math.inputs[0])
        geo = nodes.new("ShaderNodeNewGeometry")
        links.new(geo.outputs["Backfacing"], math.inputs[1])
        return checker_chain(nodes, links, coords.outputs["Object"], math.outputs[0])

    def grouped(inner_link="Object"):
        def build(nodes, links):
            tree, gin, gout = new_group("Checkers", [("Vector", "VECTOR", None), ("Scale", "VALUE", 5.0)],
                                        [("Color", "RGBA", None)])
            tree.links.new(checker_chain(tree.nodes, tree.links, gin.outputs["Vector"], gin.outputs["Scale"]),
                           gout.inputs["Color"])
            coords = nodes.new("ShaderNodeTexCoord")
            value = nodes.new("ShaderNodeValue")
            value.outputs[0].default_value = 4.0
            math = nodes.new("ShaderNodeMath")
            math.operation = "ADD"
            links.new(value.outputs[0], math.inputs[0])
            geo = nodes.new("ShaderNodeNewGeometry")
            links.new(geo.outputs["Backfacing"], math.inputs[1])
            node = group_node(nodes, tree)
            links.new(coords.outputs[inner_link], node.inputs["Vector"])
            links.new(math.outputs[0], node.inputs["Scale"])
            return node.outputs["Color"]
        return build

    def unused_input(nodes, links):
        """A group whose input B feeds only its unused output: what feeds B is not warned; a Bevel
        (unsupported) feeding the used input A is, once."""
        tree, gin, gout = new_group("Two", [("A", "RGBA", None), ("B", "RGBA", None)],
                                    [("C", "RGBA", None), ("D", "RGBA", None)])
        tree.links.new(gin.outputs["A"], gout.inputs["C"])
        tree.links.new(gin.outputs["B"], gout.inputs["D"])
        node = group_node(nodes, tree)
        links.new(nodes.new("ShaderNodeBevel").outputs[0], node.inputs["A"])
        links.new(nodes.new("ShaderNodeTexWave").outputs["Color"], node.inputs["B"])
        return node.outputs["C"]

    principled("Plain", plain, scene)
    principled("Grouped", grouped(), scene)
    principled("Other", grouped("Generated"), scene)
    principled("Unused", unused_input, scene)
    result = export()
    assert len(result.warnings) == 1 and "Material 'Unused', node 'Bevel'" in result.warnings[0], result.warnings
    m = {x.name: x for x in result.scene.materials}
    assert shape(m["Grouped"].programs["color"]) == shape(m["Plain"].programs["color"])
    assert shape(m["Other"].programs["color"]) != shape(m["Plain"].programs["color"])      # control
    names = [n.name for n in m["Grouped"].programs["color"].nodes]
    assert any(name.startswith("Group/") for name in names), names                # inner nodes named by path


class _Sock:
    def __init__(self, identifier, type_="RGBA", source=None):
        self.identifier = self.name = identifier
        self.type, self.hide_value, self.enabled, self.bl_idname = type_, False, True, "NodeSocketColor"
        self.default_value = (0.2, 0.4, 0.6, 1.0)
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


def _compile(group):
    """The compiler's result and warnings for a probe socket linked from `group`'s first output
    (stand-ins for bpy nodes: a group's tree can be missing only in a file whose library is)."""
    from engine.nodes import evaluator, registry
    from engine.scene import programs
    from mcrt_addon.export.node_graph import GraphCompiler
    from tests.nodes.group_graphs import _Table
    probe = _Node("ShaderNodeEmission", "Probe", [_Sock("Color", source=(group, group.outputs[0]))])
    table = _Table()
    graph = GraphCompiler(table, programs, evaluator, registry)
    result = graph.compile(_Tree("Mat"), probe, probe.inputs[0], "RGBA")
    return result, table.warnings, graph.warned


def test_a_group_without_its_tree_and_one_inside_itself_are_named_with_the_material():
    missing = _Node("ShaderNodeGroup", "Lost", outputs=[_Sock("Color")])
    (program, value), warnings, warned = _compile(missing)
    assert program is None and value is None and warned
    assert len(warnings) == 1 and "Material 'Mat', node 'Lost'" in warnings[0] and "without a node tree" in warnings[0]
    tree = _Tree("Loop")
    outer = _Node("ShaderNodeGroup", "Outer", outputs=[_Sock("Color")], node_tree=tree)
    inner = _Node("ShaderNodeGroup", "Inner", outputs=[_Sock("Color")], node_tree=tree)
    tree.nodes = [inner, _Node("NodeGroupOutput", "Group Output", [_Sock("Color", source=(inner, inner.outputs[0]))])]
    (program, value), warnings, warned = _compile(outer)
    assert program is None and value is None and warned
    assert len(warnings) == 1 and "node 'Inner'" in warnings[0] and "contains itself" in warnings[0], warnings
    assert "inside node group 'Loop'" in warnings[0]


@pytest.mark.parametrize("version", [(3, 4), (5, 0)])
def test_unlinked_group_vector_into_a_texture(version):
    """Before 5.0 the texture keeps its implicit coordinates (Cycles' proxies); 5.0 gives it the
    group socket's value (both measured: tests/nodes/test_node_groups_cycles.py)."""
    mat, nodes, links, out = ms.empty_material("Implicit")
    tree, gin, gout = new_group("Tex", [("Vector", "VECTOR", (0.5, 0.5, 0.5)), ("Scale", "VALUE", 3.0)],
                                [("Color", "RGBA", None)])
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(gin.outputs["Vector"], noise.inputs["Vector"])
    tree.links.new(gin.outputs["Scale"], noise.inputs["Scale"])
    tree.links.new(noise.outputs["Color"], gout.inputs["Color"])
    node = group_node(nodes, tree, Scale=7.0)
    geo = nodes.new("ShaderNodeNewGeometry")                 # a varying W keeps the graph a program
    noise.noise_dimensions = "4D"
    links.new(geo.outputs["Backfacing"], node.inputs["Scale"])
    tree.links.new(gin.outputs["Scale"], noise.inputs["W"])
    info = compiled(nodes, node.outputs["Color"], version=version)
    assert info["warnings"] == []
    program = info["program"]
    kinds = [n["type"] for n in program["nodes"]]
    if version < (5, 0):
        assert kinds == ["ShaderNodeTexCoord", "ShaderNodeNewGeometry", "ShaderNodeTexNoise"], kinds
        assert program["nodes"][0]["props"]["_outputs"] == ["Generated"]
    else:
        assert kinds == ["ShaderNodeNewGeometry", "ShaderNodeTexNoise"], kinds
        assert program["nodes"][1]["inputs"]["Vector"] == {"value": [0.5, 0.5, 0.5]}
    del mat, links, out


@pytest.mark.parametrize("version, narrowed", [((3, 4), True), ((5, 0), False)])
def test_colour_through_a_float_group_socket_is_a_float_before_50(version, narrowed):
    from engine.nodes import evaluator, registry
    from engine.scene import programs
    from mcrt_addon.export.node_graph import GraphCompiler
    from tests.nodes.group_graphs import _Table
    mat, nodes, links, out = ms.empty_material("Narrow")
    tree, gin, gout = new_group("F", [("X", "VALUE", 0.5)], [("Color", "RGBA", None)])
    tree.links.new(gin.outputs["X"], gout.inputs["Color"])
    node = group_node(nodes, tree)
    geo = nodes.new("ShaderNodeNewGeometry")
    links.new(geo.outputs["Position"], node.inputs["X"])
    probe = nodes.new("ShaderNodeEmission")
    links.new(node.outputs["Color"], probe.inputs["Color"])
    table = _Table()
    table.version = version
    program, _ = GraphCompiler(table, programs, evaluator, registry).compile(mat, probe, probe.inputs["Color"], "RGBA")
    kinds = [n.kind for n in program.nodes]
    assert kinds == (["ShaderNodeNewGeometry", "ShaderNodeMath"] if narrowed else ["ShaderNodeNewGeometry"]), kinds
