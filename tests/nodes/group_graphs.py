"""Node-group graphs for the group tests (tests/nodes/test_node_groups*.py), built in the running
Blender (5.0 in process, or 3.4 through tests/nodes/flat_quad.py): `new_group` makes a group tree
with the 3.x (`tree.inputs/outputs`) or 4.x/5.0 (`tree.interface`) interface; `build_nested` is the
flat-quad build of the nested graph; `build_group_room` a user-like scene (tests/nodes/test_node_groups_room.py);
`compiled` compiles the graph feeding a socket with the
exporter's GraphCompiler (mcrt_addon/export/node_graph.py) in that Blender, as JSON data
(engine/scene/programs.py program_json), so that the test can run it in the tracer."""
from tests.nodes import flat_quad

SOCKETS = {"VALUE": "NodeSocketFloat", "RGBA": "NodeSocketColor", "VECTOR": "NodeSocketVector"}


def new_group(name, inputs=(), outputs=()):
    """A shader node group with `inputs` / `outputs` [(name, "VALUE" | "RGBA" | "VECTOR", default)]
    and its Group Input and Group Output nodes: (tree, group input node, group output node)."""
    import bpy
    tree = bpy.data.node_groups.new(name, "ShaderNodeTree")
    for in_out, sockets in (("INPUT", inputs), ("OUTPUT", outputs)):
        for sock_name, kind, default in sockets:
            if hasattr(tree, "interface"):                       # Blender 4.0 and later
                item = tree.interface.new_socket(sock_name, in_out=in_out, socket_type=SOCKETS[kind])
            else:                                                # Blender 3.x
                item = (tree.inputs if in_out == "INPUT" else tree.outputs).new(SOCKETS[kind], sock_name)
            if default is not None:
                item.default_value = default if kind == "VALUE" else tuple(default) + ((1.0,) if kind == "RGBA" else ())
    gin = tree.nodes.new("NodeGroupInput")
    gout = tree.nodes.new("NodeGroupOutput")
    return tree, gin, gout


def group_node(nodes, tree, **values):
    """A group node of `tree` in `nodes`, its input sockets set from `values` (socket name -> value)."""
    node = nodes.new("ShaderNodeGroup")
    node.node_tree = tree
    for name, value in values.items():
        sock = node.inputs[name]
        sock.default_value = value if isinstance(value, float) else tuple(value) + ((1.0,) if sock.type == "RGBA" else ())
    return node


def warp_group():
    """Inner group: Vector x Scale + (0.3, -0.2, 0.1), a reroute and a muted Invert on the way."""
    tree, gin, gout = new_group("Warp", [("Vector", "VECTOR", None), ("Scale", "VALUE", 2.0)],
                                [("Vector", "VECTOR", None)])
    mul = tree.nodes.new("ShaderNodeVectorMath")
    mul.operation = "MULTIPLY"
    tree.links.new(gin.outputs["Vector"], mul.inputs[0])
    tree.links.new(gin.outputs["Scale"], mul.inputs[1])          # a float into a vector: grey
    reroute = tree.nodes.new("NodeReroute")
    tree.links.new(mul.outputs[0], reroute.inputs[0])
    add = tree.nodes.new("ShaderNodeVectorMath")
    add.operation = "ADD"
    add.inputs[1].default_value = (0.3, -0.2, 0.1)
    tree.links.new(reroute.outputs[0], add.inputs[0])
    muted = tree.nodes.new("ShaderNodeVectorMath")             # muted: passes its first input through
    muted.operation = "SCALE"
    muted.mute = True
    tree.links.new(add.outputs[0], muted.inputs[0])
    tree.links.new(muted.outputs[0], gout.inputs["Vector"])
    return tree


def tint_group(warp, swap=False):
    """Outer group (nests Warp): Noise at Warp(Vector, Fac x 3) multiplied by Color, mixed by Fac;
    outputs Color, Value (the colour through a Float socket: its luminance) and Spare (unlinked,
    default 0.25).  swap: the control, Color and Fac taken from each other's sockets inside."""
    tree, gin, gout = new_group("Tint", [("Vector", "VECTOR", None), ("Color", "RGBA", (0.9, 0.6, 0.3)),
                                         ("Fac", "VALUE", 0.5)],
                                [("Color", "RGBA", None), ("Value", "VALUE", None), ("Spare", "VALUE", 0.25)])
    fac, color = ("Color", "Fac") if swap else ("Fac", "Color")
    scale = tree.nodes.new("ShaderNodeMath")
    scale.operation = "MULTIPLY"
    scale.inputs[1].default_value = 3.0
    tree.links.new(gin.outputs[fac], scale.inputs[0])
    inner = tree.nodes.new("ShaderNodeGroup")
    inner.node_tree = warp
    tree.links.new(gin.outputs["Vector"], inner.inputs["Vector"])
    tree.links.new(scale.outputs[0], inner.inputs["Scale"])
    noise = tree.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 2.5
    tree.links.new(inner.outputs["Vector"], noise.inputs["Vector"])
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
    tree.links.new(gin.outputs[fac], mix.inputs["Factor"])
    tree.links.new(noise.outputs["Color"], mix.inputs[6])
    tree.links.new(gin.outputs[color], mix.inputs[7])
    tree.links.new(mix.outputs[2], gout.inputs["Color"])
    tree.links.new(mix.outputs[2], gout.inputs["Value"])
    return tree


def build_nested(nodes, links, coord, swap=False, rules=None):
    """Flat-quad build: Tint used twice (the second fed the first's colour and a mapped coordinate),
    a colour math chain after them, the Narrow and Implicit groups; one AOV per output.  The graph's
    programs are compiled for the running Blender, or for the Blender `rules` ([major, minor])."""
    warp = warp_group()
    tint = tint_group(warp, swap=swap)
    first = group_node(nodes, tint, Color=(1.0, 0.5, 0.2), Fac=0.7)
    links.new(coord, first.inputs["Vector"])
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Location"].default_value = (0.5, 0.25, 0.0)
    mapping.inputs["Scale"].default_value = (1.5, 0.75, 1.0)
    links.new(coord, mapping.inputs["Vector"])
    second = group_node(nodes, tint, Fac=0.3)
    links.new(mapping.outputs[0], second.inputs["Vector"])
    links.new(first.outputs["Color"], second.inputs["Color"])
    gamma = nodes.new("ShaderNodeGamma")
    gamma.inputs["Gamma"].default_value = 1.7
    links.new(second.outputs["Color"], gamma.inputs["Color"])
    hsv = nodes.new("ShaderNodeHueSaturation")
    hsv.inputs["Hue"].default_value = 0.6
    links.new(gamma.outputs[0], hsv.inputs["Color"])
    links.new(first.outputs["Value"], hsv.inputs["Fac"])
    narrow, gin, gout = new_group("Narrow", [("X", "VALUE", 0.5)], [("Color", "RGBA", None)])
    inside = narrow.nodes.new("ShaderNodeGamma")                # the float input into a colour socket
    narrow.links.new(gin.outputs["X"], inside.inputs["Color"])
    narrow.links.new(inside.outputs[0], gout.inputs["Color"])
    through = group_node(nodes, narrow)
    links.new(first.outputs["Color"], through.inputs["X"])      # a colour into the Float group input
    implicit, gin, gout = new_group("Implicit", [("Vector", "VECTOR", (0.3, 0.6, 0.9))],
                                    [("Texture", "VALUE", None), ("Math", "VECTOR", None), ("Mapped", "VECTOR", None)])
    gradient = implicit.nodes.new("ShaderNodeTexGradient")       # its hidden Vector: Generated when unlinked
    implicit.links.new(gin.outputs["Vector"], gradient.inputs["Vector"])
    implicit.links.new(gradient.outputs["Fac"], gout.inputs["Texture"])
    add = implicit.nodes.new("ShaderNodeVectorMath")             # a plain Vector: the group socket's value
    add.inputs[1].default_value = (0.0, 0.0, 0.0)
    implicit.links.new(gin.outputs["Vector"], add.inputs[0])
    implicit.links.new(add.outputs[0], gout.inputs["Math"])
    mapping = implicit.nodes.new("ShaderNodeMapping")
    mapping.inputs["Location"].default_value = (0.1, 0.0, 0.0)
    implicit.links.new(gin.outputs["Vector"], mapping.inputs["Vector"])
    implicit.links.new(mapping.outputs[0], gout.inputs["Mapped"])
    unlinked = group_node(nodes, implicit)
    geo = nodes.new("ShaderNodeNewGeometry")
    result = {"first": first.outputs["Color"], "second": second.outputs["Color"],
              "value": first.outputs["Value"], "spare": second.outputs["Spare"], "chain": hsv.outputs[0],
              "narrow": through.outputs["Color"], "implicit": unlinked.outputs["Texture"],
              "math": unlinked.outputs["Math"], "mapped": unlinked.outputs["Mapped"], "P": geo.outputs["Position"]}
    flat_quad.KEPT["programs"] = {name: compiled(nodes, sock, version=rules) for name, sock in result.items()}
    return result


class _Table:
    """What GraphCompiler needs of export/materials.py MaterialTable: warn, images, version."""

    def __init__(self):
        import bpy
        self.warnings, self.images, self.version = [], None, tuple(bpy.app.version[:2])

    def warn(self, mat, node, text):
        self.warnings.append(f"Material '{mat.name}', node '{getattr(node, 'name', '')}': {text}")


def compiled(nodes, sock, target="RGBA", version=None):
    """The program (JSON data) of the graph feeding output `sock`, through a probe Emission node's
    Color (removed again), and the compiler's warnings: {"program": ..., "warnings": [...]}; version:
    the Blender the compiler takes the scene for (default: the running one)."""
    from engine.nodes import evaluator, registry
    from engine.scene import programs
    from mcrt_addon.export.node_graph import GraphCompiler
    tree = sock.id_data
    probe = nodes.new("ShaderNodeEmission")
    tree.links.new(sock, probe.inputs["Color"])
    table = _Table()
    table.version = tuple(version or table.version)
    compiler = GraphCompiler(table, programs, evaluator, registry)
    program, value = compiler.compile(tree, probe, probe.inputs["Color"], target)
    nodes.remove(probe)
    return {"program": None if program is None else programs.program_json(program),
            "value": value, "warnings": table.warnings}


# -- a user-like scene: the room of sample_blends/make_samples.py with a marble node group --------------
def ms():
    """sample_blends/make_samples.py (the scene helpers), imported on first use."""
    import os
    import sys
    here = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "sample_blends")
    if here not in sys.path:
        sys.path.insert(0, here)
    import make_samples
    return make_samples


def marble_group():
    """Noise (scale from the group input) -> Color Ramp -> the mix of the Vein and Stone colours."""
    tree, gin, gout = new_group("Marble", [("Vector", "VECTOR", None), ("Scale", "VALUE", 4.0),
                                           ("Vein", "RGBA", (0.05, 0.05, 0.08)), ("Stone", "RGBA", (0.9, 0.88, 0.8))],
                                [("Color", "RGBA", None)])
    noise = tree.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Detail"].default_value = 6.0
    tree.links.new(gin.outputs["Vector"], noise.inputs["Vector"])
    tree.links.new(gin.outputs["Scale"], noise.inputs["Scale"])
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position, ramp.color_ramp.elements[1].position = 0.42, 0.58
    tree.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    tree.links.new(ramp.outputs["Color"], mix.inputs["Factor"])
    tree.links.new(gin.outputs["Vein"], mix.inputs[6])
    tree.links.new(gin.outputs["Stone"], mix.inputs[7])
    tree.links.new(mix.outputs[2], gout.inputs["Color"])
    return tree


def marble_material(name, tree, object_space, **values):
    """A Principled BSDF whose Base Color is the Marble group of Position (object_space: through a
    Vector Transform from World to Object)."""
    mat, nodes, links, out = ms().empty_material(name)
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Roughness"].default_value = 0.35
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    group = group_node(nodes, tree, **values)
    geo = nodes.new("ShaderNodeNewGeometry")
    if object_space:
        vt = nodes.new("ShaderNodeVectorTransform")
        vt.vector_type, vt.convert_from, vt.convert_to = "POINT", "WORLD", "OBJECT"
        links.new(geo.outputs["Position"], vt.inputs["Vector"])
        links.new(vt.outputs["Vector"], group.inputs["Vector"])
    else:
        links.new(geo.outputs["Position"], group.inputs["Vector"])
    links.new(group.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def build_group_room(path, res):
    """The room (Cornell box) whose floor and ball take their Base Color from the Marble group, used
    twice with different inputs (the ball's coordinates through a Vector Transform), saved at path."""
    import math

    import bpy
    m = ms()
    scene = m.reset()
    mats = dict(white=m.diffuse("White", (0.73, 0.73, 0.73)), red=m.diffuse("Red", (0.65, 0.05, 0.05)),
                green=m.diffuse("Green", (0.12, 0.45, 0.15)), light=m.emission("Lamp", (1.0, 1.0, 1.0), 14.0))
    m.room(scene, mats, light_size=0.6)
    tree = marble_group()
    floor = bpy.data.objects["Floor"]
    floor.data.materials.clear()
    floor.data.materials.append(marble_material("MarbleFloor", tree, False, Scale=3.0))
    ball = marble_material("MarbleBall", tree, True, Scale=6.0, Vein=(0.5, 0.05, 0.02), Stone=(0.95, 0.75, 0.3))
    m.mesh_object(scene, "Ball", lambda bm: m.uv_sphere(bm, 0.35), ball, location=(0.2, 0.1, 0.5),
                  rotation=(0.0, 0.0, math.radians(40)), smooth=True)
    m.camera(scene)
    m.black_world(scene)
    m.settings(scene, res)
    bpy.ops.wm.save_as_mainfile(filepath=path)
