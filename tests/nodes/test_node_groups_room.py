"""A user-like scene against Cycles 5.0 (tests/addon/rendering.py agreement method): the room whose
floor and ball take their Principled Base Color from one node group used twice with different inputs,
the ball's coordinates through a Vector Transform (tests/nodes/group_graphs.py build_group_room).  It
exports without a warning, both Base Colors as programs, and agrees; CONTROL: the group's two colours
exchanged in the exported programs fails."""
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
    import rendering as R

    from tests.nodes.group_graphs import build_group_room
    path = str(tmp_path_factory.mktemp("groups") / "group_room.blend")
    build_group_room(path, R.RES)
    exported = R.export_blend(path, R.RES)
    return exported, R.cycles_runs(path, R.RES, R.SPP, R.DEPTH, seeds=range(1, R.K + 1))


def test_group_room_agrees_with_cycles(room):
    import rendering as R
    from imagecompare import compare_runs
    exported, reference = room
    assert exported.warnings == [], exported.warnings
    programs = {m.name: sorted(m.programs) for m in exported.scene.materials if m.programs}
    assert programs == {"MarbleFloor": ["color"], "MarbleBall": ["color"]}
    result = compare_runs(R.tncg15_agreement_runs(exported.scene), reference, tau=TAU)
    print(f"group room: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_the_group_colours_exchanged(room):
    """CONTROL: in every program, the Mix node's two colours (the group's Vein and Stone) exchanged."""
    import rendering as R
    from imagecompare import compare_runs
    exported, reference = room
    scene = copy.deepcopy(exported.scene)
    for m in scene.materials:
        for program in (m.programs or {}).values():
            for node in program.nodes:
                if node.kind == "ShaderNodeMix":
                    node.inputs["A_Color"], node.inputs["B_Color"] = node.inputs["B_Color"], node.inputs["A_Color"]
    result = compare_runs(R.tncg15_agreement_runs(scene, 2000), reference, tau=TAU)
    print(f"group room, colours exchanged: {result.summary()}")
    assert not result.passed, result.summary()
