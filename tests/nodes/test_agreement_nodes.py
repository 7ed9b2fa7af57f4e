"""TNCG15 MC agrees with Cycles 5.0 on a room whose materials are node graphs (tests/nodes/node_scene.py:
Texture Coordinate Object -> Mapping -> Image Texture into Base Color, an Image Texture at Generated
coordinates into Roughness, Geometry Normal -> Mapping into a Diffuse colour, Texture Coordinate
Generated into an Emission colour), and the comparison catches a Mapping scale off by 10 %.

Method as tests/addon/test_agreement_materials.py: 64 x 64, 32 spp, max depth 8, K = 4 seeds each."""
import copy
import os
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "addon"))

pytestmark = pytest.mark.slow
TAU = 0.02


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    from rendering import RES, cycles_reference, export_blend
    from tests.nodes import node_scene
    path = node_scene.build(str(tmp_path_factory.mktemp("nodes") / "node_room.blend"))
    exported = export_blend(path, RES)
    return exported, cycles_reference(path, "node_room")


def test_node_room_exports_programs(room):
    exported, _ = room
    programs = {m.name: sorted(m.programs) for m in exported.scene.materials if m.programs}
    assert programs == {"NodeFloor": ["color", "roughness"], "NodeBall": ["color"], "NodeLamp": ["emission"]}
    assert not [w for w in exported.warnings if "not" in w], exported.warnings


def test_node_room_agrees_with_cycles(room):
    from imagecompare import compare_runs
    from rendering import tncg15_agreement_runs, to_png
    exported, reference = room
    ours = tncg15_agreement_runs(exported.scene)
    to_png(ours.mean(0), "/tmp/node_room_ours.png", 4)
    to_png(reference.mean(0), "/tmp/node_room_cycles.png", 4)
    result = compare_runs(ours, reference, tau=TAU)
    print(f"node_room: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_mapping_scale_off_by_10_percent(room):
    from imagecompare import compare_runs
    from rendering import tncg15_agreement_runs
    exported, reference = room
    scene = copy.deepcopy(exported.scene)
    floor = next(m for m in scene.materials if m.name == "NodeFloor")
    mapping = next(n for n in floor.programs["color"].nodes if n.kind == "ShaderNodeMapping")
    mapping.inputs["Scale"] = tuple(1.1 * c for c in mapping.inputs["Scale"])
    result = compare_runs(tncg15_agreement_runs(scene, first_seed=2000), reference, tau=TAU)
    print(f"node_room, mapping scale x 1.1: {result.summary()}")
    assert not result.passed, result.summary()
