"""Shader node groups for tests/nodes/test_shader_groups*.py, built in the running Blender (5.0 in
process, 3.4 in a subprocess): a Principled BSDF whose base colour is an image times a tint and whose
roughness is a Noise texture, built either inside a group (its Tint, Scale and Metallic the group's
inputs, its BSDF the group's Shader output) or straight in the material with the same values; a
"Coat" group mixing a shader input with a Glossy BSDF inside by a group input factor."""
import dataclasses

import bpy

SOCKETS = {"VALUE": "NodeSocketFloat", "RGBA": "NodeSocketColor", "VECTOR": "NodeSocketVector",
           "SHADER": "NodeSocketShader"}


def canonical(value):
    """A material as plain data without names (a group's inner nodes are named by their path; a mix
    factor names the node it was read from for messages: the Group Input inside a group)."""
    if dataclasses.is_dataclass(value):
        skip = ("name", "node") if type(value).__name__ == "MixFactor" else ("name",)
        return {f.name: canonical(getattr(value, f.name)) for f in dataclasses.fields(value) if f.name not in skip}
    if isinstance(value, dict):
        return {k: canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [canonical(v) for v in value]
    return value


def new_group(name, inputs=(), outputs=()):
    """A shader group with `inputs` / `outputs` [(name, type)] (3.x or 4.x/5.0 interface): (tree,
    Group Input node, Group Output node)."""
    tree = bpy.data.node_groups.new(name, "ShaderNodeTree")
    for in_out, sockets in (("INPUT", inputs), ("OUTPUT", outputs)):
        for sock_name, kind in sockets:
            if hasattr(tree, "interface"):
                tree.interface.new_socket(sock_name, in_out=in_out, socket_type=SOCKETS[kind])
            else:
                (tree.inputs if in_out == "INPUT" else tree.outputs).new(SOCKETS[kind], sock_name)
    return tree, tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")


def by_id(sockets, identifier):
    return next(s for s in sockets if s.identifier == identifier)


def tiles():
    """A generated 16 x 16 colour grid image (no file), made once."""
    image = bpy.data.images.get("Tiles")
    if image is None:
        image = bpy.data.images.new("Tiles", 16, 16)
        image.generated_type = "COLOR_GRID"
    return image


def feed(links, value, sock):
    """`value` into the input `sock`: an output socket is linked, anything else is its value."""
    if hasattr(value, "links") and hasattr(value, "node") and value.is_output:
        links.new(value, sock)
    else:
        sock.default_value = tuple(value) + (1.0,) if sock.type == "RGBA" else value


def principled_chain(nodes, links, tint, scale, metallic):
    """Principled(Base Color = Tiles x tint, Roughness = MapRange(Noise(scale)) in [0.15, 0.85],
    Metallic = metallic): its BSDF output.  Each value: an output socket (linked) or a constant."""
    image = nodes.new("ShaderNodeTexImage")
    image.image = tiles()
    mix = nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
    by_id(mix.inputs, "Factor_Float").default_value = 1.0
    links.new(image.outputs["Color"], by_id(mix.inputs, "A_Color"))
    feed(links, tint, by_id(mix.inputs, "B_Color"))
    noise = nodes.new("ShaderNodeTexNoise")
    feed(links, scale, noise.inputs["Scale"])
    ramp = nodes.new("ShaderNodeMapRange")
    ramp.inputs["To Min"].default_value, ramp.inputs["To Max"].default_value = 0.15, 0.85
    links.new(noise.outputs["Fac"], ramp.inputs["Value"])
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    links.new(by_id(mix.outputs, "Result_Color"), bsdf.inputs["Base Color"])
    links.new(ramp.outputs["Result"], bsdf.inputs["Roughness"])
    feed(links, metallic, bsdf.inputs["Metallic"])
    return bsdf.outputs[0], noise


def surface_group(name="Surface"):
    """The principled chain in a group: inputs Tint, Scale, Metallic; output Shader."""
    tree, gin, gout = new_group(name, [("Tint", "RGBA"), ("Scale", "VALUE"), ("Metallic", "VALUE")],
                                [("Shader", "SHADER")])
    shader, _ = principled_chain(tree.nodes, tree.links, gin.outputs["Tint"], gin.outputs["Scale"],
                                 gin.outputs["Metallic"])
    tree.links.new(shader, gout.inputs["Shader"])
    return tree


def changed_group():
    """CONTROL: the Surface group with one inner link changed: the image's Alpha (1) tints, not its Color."""
    tree = surface_group("Changed")
    image = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeTexImage")
    mix = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeMix")
    tree.links.new(image.outputs["Alpha"], by_id(mix.inputs, "A_Color"))
    return tree


def wrapper_group(inner):
    """A group holding a group node of `inner` (nested), with a reroute and a muted Add Shader
    (it passes its first shader through) on the way to its output, passing its inputs on."""
    tree, gin, gout = new_group("Wrapper", [("Tint", "RGBA"), ("Scale", "VALUE"), ("Metallic", "VALUE")],
                                [("Shader", "SHADER")])
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = inner
    for name in ("Tint", "Scale", "Metallic"):
        tree.links.new(gin.outputs[name], node.inputs[name])
    reroute = tree.nodes.new("NodeReroute")
    tree.links.new(node.outputs["Shader"], reroute.inputs[0])
    add = tree.nodes.new("ShaderNodeAddShader")
    add.mute = True
    tree.links.new(reroute.outputs[0], add.inputs[0])
    tree.links.new(tree.nodes.new("ShaderNodeEmission").outputs[0], add.inputs[1])
    tree.links.new(add.outputs[0], gout.inputs["Shader"])
    return tree


def group_material(name, tree, tint, scale, metallic):
    """A material whose Surface is a group node of `tree` with these inputs (values or a callable
    (nodes, links) -> output socket, linked from outside): (material, group node)."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    out = nodes.new("ShaderNodeOutputMaterial")
    group = nodes.new("ShaderNodeGroup")
    group.node_tree = tree
    for key, value in (("Tint", tint), ("Scale", scale), ("Metallic", metallic)):
        feed(links, value(nodes, links) if callable(value) else value, group.inputs[key])
    links.new(group.outputs["Shader"], out.inputs["Surface"])
    return mat, group


def plain_material(name, tint, scale, metallic):
    """The same chain straight in a material (a callable input: made in the material, linked)."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    out = nodes.new("ShaderNodeOutputMaterial")
    values = [v(nodes, links) if callable(v) else v for v in (tint, scale, metallic)]
    shader, _ = principled_chain(nodes, links, *values)
    links.new(shader, out.inputs["Surface"])
    return mat


def value_node(value):
    """A callable making a Value node of `value` (an input linked from outside the group)."""
    def make(nodes, links):
        node = nodes.new("ShaderNodeValue")
        node.outputs[0].default_value = value
        return node.outputs[0]
    return make


def coat_group():
    """Mix Shader(Fac = group input Fac, Base = group input shader, a Glossy BSDF inside)."""
    tree, gin, gout = new_group("Coat", [("Fac", "VALUE"), ("Base", "SHADER")], [("Shader", "SHADER")])
    mix = tree.nodes.new("ShaderNodeMixShader")
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Roughness"].default_value = 0.3
    tree.links.new(gin.outputs["Fac"], mix.inputs["Fac"])
    tree.links.new(gin.outputs["Base"], mix.inputs[1])
    tree.links.new(glossy.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], gout.inputs["Shader"])
    return tree


# (tint, scale, metallic) of the floor and the ball: one Surface group, two sets of inputs.
FLOOR_INPUTS = ((0.9, 0.85, 0.8), 3.0, 0.0)
BALL_INPUTS = ((0.95, 0.45, 0.1), 12.0, 1.0)


def build_shader_group_room(path, res):
    """The room of sample_blends/make_samples.py whose floor and ball are the Surface group (a
    Principled BSDF with an image-tinted base colour and a Noise-driven roughness, wrapped in the
    Wrapper group) with FLOOR_INPUTS and BALL_INPUTS, saved at `path`."""
    import math
    import os
    import sys
    here = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "sample_blends")
    if here not in sys.path:
        sys.path.insert(0, here)
    import make_samples as m
    scene = m.reset()
    mats = dict(white=m.diffuse("White", (0.73, 0.73, 0.73)), red=m.diffuse("Red", (0.65, 0.05, 0.05)),
                green=m.diffuse("Green", (0.12, 0.45, 0.15)), light=m.emission("Lamp", (1.0, 1.0, 1.0), 14.0))
    m.room(scene, mats, light_size=0.6)
    tree = wrapper_group(surface_group())
    floor = bpy.data.objects["Floor"]
    floor.data.materials.clear()
    floor.data.materials.append(group_material("GroupFloor", tree, *FLOOR_INPUTS)[0])
    floor.data.uv_layers.new(name="UVMap")
    ball = m.mesh_object(scene, "Ball", lambda bm: m.uv_sphere(bm, 0.35), group_material("GroupBall", tree, *BALL_INPUTS)[0],
                         location=(0.2, 0.1, 0.5), rotation=(0.0, 0.0, math.radians(40)), smooth=True)
    ball.data.uv_layers.new(name="UVMap")
    m.camera(scene)
    m.black_world(scene)
    m.settings(scene, res)
    bpy.ops.wm.save_as_mainfile(filepath=path)
