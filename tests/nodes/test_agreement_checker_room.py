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
from tests.nodes.agreement import against_cycles, compared

NODES = ("ShaderNodeTexChecker", "ShaderNodeTexNoise", "ShaderNodeSeparateXYZ", "ShaderNodeMath")
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not all(supported(n) for n in NODES), reason="the texture or math kernels are not merged")]


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    from rendering import RES
    from tests.nodes import node_scene
    path = node_scene.build_checker_room(str(tmp_path_factory.mktemp("nodes") / "checker_room.blend"), RES)
    return against_cycles(path, "checker_room")


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
