"""TNCG15 MC agrees with Cycles 5.0 on a room whose materials are node graphs (tests/nodes/node_scene.py:
Texture Coordinate Object -> Mapping -> Image Texture into Base Color, an Image Texture at Generated
coordinates into Roughness, Geometry Normal -> Mapping into a Diffuse colour, Texture Coordinate
Generated into an Emission colour), and the comparison catches a Mapping scale off by 10 %.

Method as tests/addon/test_agreement_materials.py: 64 x 64, 32 spp, max depth 8, K = 4 seeds each."""
import copy

import pytest

from tests.nodes.agreement import against_cycles, compared

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    from tests.nodes import node_scene
    return against_cycles(node_scene.build(str(tmp_path_factory.mktemp("nodes") / "node_room.blend")), "node_room")


def test_node_room_exports_programs(room):
    exported, _ = room
    programs = {m.name: sorted(m.programs) for m in exported.scene.materials if m.programs}
    assert programs == {"NodeFloor": ["color", "roughness"], "NodeBall": ["color"], "NodeLamp": ["emission"]}
    assert not [w for w in exported.warnings if "not" in w], exported.warnings


def test_node_room_agrees_with_cycles(room):
    exported, reference = room
    result = compared(exported.scene, reference, "node_room", png="node_room")
    assert result.passed, result.summary()


def test_comparison_catches_mapping_scale_off_by_10_percent(room):
    exported, reference = room
    scene = copy.deepcopy(exported.scene)
    floor = next(m for m in scene.materials if m.name == "NodeFloor")
    mapping = next(n for n in floor.programs["color"].nodes if n.kind == "ShaderNodeMapping")
    mapping.inputs["Scale"] = tuple(1.1 * c for c in mapping.inputs["Scale"])
    result = compared(scene, reference, "node_room, mapping scale x 1.1", first_seed=2000)
    assert not result.passed, result.summary()
