"""TNCG15 MC agrees with Cycles of the running Blender on emitters built of shader mixes
(mcrt_addon/export/shader_mix.py): a diffuse room whose ceiling lamp is Diffuse + Emission through an
Add Shader (as scenes converted from other renderers light themselves) and with a ball that is a Mix
Shader of a Diffuse and an Emission; and the comparison catches the lamp's emission dropped (the old
export: a grey diffuse lamp) and the Mix factor ignored.

Method and settings as tests/addon/test_agreement_materials.py: 64 x 64, 32 spp, max depth 8, K = 4
seeds each, 8 x 8 block means and the image mean within the Sidak-corrected z bound plus tau.
"""
import copy
import math

import bpy
import pytest

from imagecompare import compare_runs
from rendering import RES, cycles_reference, export_blend, tncg15_agreement_runs

# Cycles renders: `make test-slow` (the mix's own tests: tests/materials/test_mix.py run in `make test`).
pytestmark = pytest.mark.slow

TAU = 0.02
LAMP_STRENGTH = 12.0
BALL_STRENGTH, BALL_FAC = 6.0, 0.5
_cache = {}


def shader_graph(name, build):
    """A material whose surface is ``build(nodes, links)``'s node."""
    mat = bpy.data.materials.new(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    out = nodes.new("ShaderNodeOutputMaterial")
    links.new(build(nodes, links).outputs[0], out.inputs["Surface"])
    return mat


def diffuse_and_emission(nodes, rgb, emission_rgb, strength):
    d = nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*rgb, 1.0)
    e = nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = (*emission_rgb, 1.0)
    e.inputs["Strength"].default_value = strength
    return d, e


def add_lamp(nodes, links):
    d, e = diffuse_and_emission(nodes, (0.5, 0.5, 0.5), (1.0, 0.9, 0.75), LAMP_STRENGTH)
    add = nodes.new("ShaderNodeAddShader")
    links.new(e.outputs[0], add.inputs[0])           # emission first, as converted scenes write it
    links.new(d.outputs[0], add.inputs[1])
    return add


def mix_ball(nodes, links):
    d, e = diffuse_and_emission(nodes, (0.7, 0.6, 0.2), (0.3, 0.6, 1.0), BALL_STRENGTH)
    mix = nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = BALL_FAC
    links.new(d.outputs[0], mix.inputs[1])
    links.new(e.outputs[0], mix.inputs[2])
    return mix


@pytest.fixture(scope="module")
def blend(tmp_path_factory, make_samples_module, addon):
    ms = make_samples_module
    scene = ms.reset()
    ms.room(scene, dict(white=ms.diffuse("White", (0.73, 0.73, 0.73)), red=ms.diffuse("Red", (0.65, 0.05, 0.05)),
                        green=ms.diffuse("Green", (0.12, 0.45, 0.15)),
                        light=shader_graph("AddLamp", add_lamp)))
    ms.mesh_object(scene, "Box", lambda bm: ms.cube(bm, 1.0), bpy.data.materials["White"],
                   location=(-0.35, 0.3, 0.4), rotation=(0, 0, math.radians(20)), scale=(0.3, 0.3, 0.4))
    ms.mesh_object(scene, "Ball", lambda bm: ms.uv_sphere(bm, 0.2), shader_graph("MixBall", mix_ball),
                   location=(0.4, 0.0, 0.2), smooth=True)
    ms.camera(scene)
    ms.black_world(scene)
    ms.settings(scene, RES)
    path = str(tmp_path_factory.mktemp("shader_mix") / "add_lamp_room.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, compress=True, check_existing=False)
    return path


def reference(blend):
    if "ref" not in _cache:
        _cache["ref"] = cycles_reference(blend)
    return _cache["ref"]


def exported(blend):
    if "scene" not in _cache:
        _cache["scene"] = export_blend(blend, RES)
    return _cache["scene"]


def ours(scene, first_seed=1000):
    return tncg15_agreement_runs(scene, first_seed)


def material(scene, name):
    return next(m for m in scene.materials if m.name == name)


def test_add_shader_lamp_room_agrees_with_cycles(blend):
    res = exported(blend)
    assert res.warnings == [], res.warnings
    lamp, ball = material(res.scene, "AddLamp"), material(res.scene, "MixBall")
    assert lamp.kind == "diffuse" and lamp.emission == pytest.approx((12.0, 10.8, 9.0))
    assert ball.color == pytest.approx((0.35, 0.3, 0.1)) and ball.emission == pytest.approx((0.9, 1.8, 3.0))
    result = compare_runs(ours(res.scene), reference(blend), tau=TAU)
    print(f"add_lamp_room: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_the_lamps_emission_dropped(blend):
    """Control: the Add Shader lamp without its emission (the old export: a grey diffuse lamp)."""
    scene = copy.deepcopy(exported(blend).scene)
    material(scene, "AddLamp").emission = (0.0, 0.0, 0.0)
    result = compare_runs(ours(scene, first_seed=2000), reference(blend), tau=TAU)
    print(f"add_lamp_room, lamp emission dropped: {result.summary()}")
    assert not result.passed, result.summary()


def test_comparison_catches_the_mix_factor_ignored(blend):
    """Control: the ball's emission at full strength (the Mix Shader's weight on it ignored)."""
    scene = copy.deepcopy(exported(blend).scene)
    ball = material(scene, "MixBall")
    ball.emission = tuple(c / BALL_FAC for c in ball.emission)
    result = compare_runs(ours(scene, first_seed=3000), reference(blend), tau=TAU)
    print(f"add_lamp_room, mix factor ignored: {result.summary()}")
    assert not result.passed, result.summary()
