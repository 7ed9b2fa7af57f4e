"""The node-graph room of the Cycles agreement tests (tests/nodes/test_agreement_nodes.py): the
"node_room" scene of sample_blends/make_samples.py, written to a .blend in the running bpy; and the
checker room (tests/nodes/test_agreement_checker_room.py, tests/nodes/test_blender34_nodes.py): the
node room with a procedural floor, built in bpy 5.0 or in Blender 3.4 (tests/addon/blender34_reference.py)."""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "sample_blends"))

import make_samples as ms  # noqa: E402

SCALE = ms.NODE_ROOM_SCALE


def build(path, resolution=(64, 64)):
    """The node room at `resolution`, saved as `path` (returned)."""
    made = ms.make("node_room", os.path.dirname(path), tuple(resolution))
    if os.path.abspath(made) != os.path.abspath(path):
        os.replace(made, path)
    return path


def checker_floor():
    """The checker room's floor: a Principled BSDF whose Base Color is a Checker Texture (scale 6) at its
    implicit Generated coordinates, its Roughness Texture Coordinate Object -> Separate XYZ -> Math
    (x * 0.3 + 0.4) and its Metallic a Noise Texture's Fac."""
    mat, nodes, links, out = ms.empty_material("Checkered")
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    checker, noise = nodes.new("ShaderNodeTexChecker"), nodes.new("ShaderNodeTexNoise")
    checker.inputs["Scale"].default_value = 6.0
    coords, separate, math = nodes.new("ShaderNodeTexCoord"), nodes.new("ShaderNodeSeparateXYZ"), nodes.new("ShaderNodeMath")
    math.operation = "MULTIPLY_ADD"
    math.inputs[1].default_value, math.inputs[2].default_value = 0.3, 0.4
    links.new(coords.outputs["Object"], separate.inputs[0])
    links.new(separate.outputs["X"], math.inputs[0])
    links.new(checker.outputs["Color"], bsdf.inputs["Base Color"])
    links.new(math.outputs[0], bsdf.inputs["Roughness"])
    links.new(noise.outputs["Fac"], bsdf.inputs["Metallic"])
    return mat


def build_checker_room(path, resolution=(64, 64)):
    """The node room with the checker floor at `resolution`, saved as `path` (returned)."""
    import bpy
    ms.reset()
    ms.make_node_room(bpy.context.scene, tuple(resolution))
    floor = bpy.data.objects["Floor"]
    floor.data.materials.clear()
    floor.data.materials.append(checker_floor())
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return path
