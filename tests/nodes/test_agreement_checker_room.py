"""After the node branches merge: the node room (sample_blends/make_samples.py) with its floor a Principled
BSDF whose Base Color is a Checker Texture at its implicit Generated coordinates, its Roughness Texture
Coordinate Object -> Separate XYZ -> Math (Multiply Add) and its Metallic a Noise Texture, against
Cycles 5.0; the control (the checker's scale 10 % larger) fails.  Skipped while the tracer has no
kernel for one of these nodes (engine/nodes/registry.py).

Measured on the merged branches (nodes-core, nodes-math, nodes-textures): image mean 0.1468 vs 0.1468,
0 of 193 blocks beyond the bound; control 16 of 193."""
import copy

import pytest

from engine.nodes.registry import supported
from tests.nodes.agreement import against_cycles, compared, saved

NODES = ("ShaderNodeTexChecker", "ShaderNodeTexNoise", "ShaderNodeSeparateXYZ", "ShaderNodeMath")
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not all(supported(n) for n in NODES), reason="the texture or math kernels are not merged")]


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    import bpy
    from rendering import RES
    from tests.nodes import node_scene
    ms = node_scene.ms
    ms.reset()
    ms.make_node_room(bpy.context.scene, RES)
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
    floor = bpy.data.objects["Floor"]
    floor.data.materials.clear()
    floor.data.materials.append(mat)
    return against_cycles(saved(tmp_path_factory, "checker_room"), "checker_room")


def test_checker_room_agrees_with_cycles(room):
    exported, reference = room
    assert exported.warnings == [], exported.warnings
    result = compared(exported.scene, reference, "checker_room")
    assert result.passed, result.summary()


def test_comparison_catches_the_checker_scale_off_by_10_percent(room):
    exported, reference = room
    scene = copy.deepcopy(exported.scene)
    floor = next(m for m in scene.materials if m.name == "Checkered")
    checker = next(n for n in floor.programs["color"].nodes if n.kind == "ShaderNodeTexChecker")
    checker.inputs["Scale"] = 1.1 * checker.inputs["Scale"]
    result = compared(scene, reference, "checker_room, checker scale x 1.1", first_seed=2000)
    assert not result.passed, result.summary()
