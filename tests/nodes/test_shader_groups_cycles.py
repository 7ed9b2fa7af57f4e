"""A user-like scene against Cycles 5.0 (tests/addon/rendering.py agreement method): the room whose
floor and ball are one shader group (a Principled BSDF with an image-tinted base colour and a
Noise-driven roughness, inside a group nested in another) with different group inputs
(tests/nodes/shader_group_graphs.py build_shader_group_room).  It exports without a warning, both
materials principled with colour and roughness programs, and agrees; CONTROL: the two materials'
group inputs exchanged (the floor gets the ball's, the ball the floor's) fails."""
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

    from tests.nodes.shader_group_graphs import build_shader_group_room
    path = str(tmp_path_factory.mktemp("shader_groups") / "shader_group_room.blend")
    build_shader_group_room(path, R.RES)
    exported = R.export_blend(path, R.RES)
    return exported, R.cycles_runs(path, R.RES, R.SPP, R.DEPTH, seeds=range(1, R.K + 1))


def test_shader_group_room_agrees_with_cycles(room):
    import rendering as R
    from imagecompare import compare_runs
    exported, reference = room
    assert exported.warnings == [], exported.warnings
    kinds = {m.name: (m.kind, sorted(m.programs or {})) for m in exported.scene.materials if m.name.startswith("Group")}
    assert kinds == {"GroupFloor": ("principled", ["color", "roughness"]),
                     "GroupBall": ("principled", ["color", "roughness"])}, kinds
    result = compare_runs(R.tncg15_agreement_runs(exported.scene), reference, tau=TAU)
    print(f"shader group room: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_the_group_inputs_exchanged(room):
    """CONTROL: the floor's and the ball's materials (they differ only in their group inputs) exchanged."""
    import rendering as R
    from imagecompare import compare_runs
    exported, reference = room
    scene = copy.deepcopy(exported.scene)
    names = [m.name for m in scene.materials]
    i, j = names.index("GroupFloor"), names.index("GroupBall")
    scene.materials[i], scene.materials[j] = scene.materials[j], scene.materials[i]
    result = compare_runs(R.tncg15_agreement_runs(scene, 2000), reference, tau=TAU)
    print(f"shader group room, group inputs exchanged: {result.summary()}")
    assert not result.passed, result.summary()
