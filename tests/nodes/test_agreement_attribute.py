"""A colour attribute through the Attribute node (mcrt_addon/export/mesh.py corner_colors, engine/nodes/
inputs.py attribute) agrees with Cycles 5.0: the node room's ball painted per vertex (a point-domain
FLOAT_COLOR attribute: green on the upper half, random red and blue) into its Diffuse Color; the
control (the attribute's red and green swapped) fails."""
import copy

import pytest

from tests.nodes.agreement import against_cycles, compared, saved

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    import bpy
    import numpy as np
    from rendering import RES
    from tests.nodes import node_scene
    ms = node_scene.ms
    ms.reset()
    ms.make_node_room(bpy.context.scene, RES)
    ball = bpy.data.objects["Ball"]
    paint = ball.data.color_attributes.new("Paint", "FLOAT_COLOR", "POINT")
    rng = np.random.default_rng(7)
    z = np.array([v.co.z for v in ball.data.vertices])
    for value, height, c in zip(paint.data, z, rng.random((len(z), 3))):
        value.color = (0.9 * c[0], 0.5 + 0.4 * np.sign(height) * 0.9, 0.2 + 0.6 * c[2], 1.0)
    mat, nodes, links, out = ms.empty_material("Painted")
    bsdf, attr = nodes.new("ShaderNodeBsdfDiffuse"), nodes.new("ShaderNodeAttribute")
    attr.attribute_name = "Paint"
    links.new(attr.outputs["Color"], bsdf.inputs["Color"])
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    ball.data.materials.clear()
    ball.data.materials.append(mat)
    return against_cycles(saved(tmp_path_factory, "painted_room"), "painted_room")


def test_painted_ball_agrees_with_cycles(room):
    exported, reference = room
    assert exported.warnings == [], exported.warnings
    assert "Paint" in next(m for m in exported.scene.meshes if m.name == "Ball").colors
    result = compared(exported.scene, reference, "painted_room")
    assert result.passed, result.summary()


def test_comparison_catches_red_and_green_swapped(room):
    exported, reference = room
    scene = copy.deepcopy(exported.scene)
    ball = next(m for m in scene.meshes if m.name == "Ball")
    ball.colors["Paint"] = ball.colors["Paint"][..., [1, 0, 2]].copy()
    result = compared(scene, reference, "painted_room, red and green swapped", first_seed=2000)
    assert not result.passed, result.summary()
