"""The `normal_map` sample scene (sample_blends/make_samples.py: a smooth UV sphere whose Principled
BSDF's Normal is a tangent-space Normal Map of an Image Texture, the domes of
scripts/make_sample_normal_map.py packed as an 8-bit Non-Color image, on a floor under a low sun and
a dim sky) against Cycles 5.0 (bpy) and Cycles 3.4 (Debian's Blender 3.4, its Principled v1).
Controls: the image's green channel flipped (a DirectX-convention map) and the Normal Map's strength
0 fail.

Method as tests/addon/test_agreement_materials.py: 64 x 64, 32 spp, max depth 8, K = 4 seeds each
(docs/nodes.md "Normals" gives the measured figures)."""
import copy

import numpy as np
import pytest

from tests.nodes.agreement import TAU, against_cycles, compared

pytestmark = pytest.mark.slow
PROGRAMS = {"NormalMapped": ["normal"]}


def green_flipped(scene):
    """CONTROL: the normal map's green channel g -> 1 - g (the bitangent's direction reversed)."""
    scene = copy.deepcopy(scene)
    for texture in scene.textures:
        if texture.name == "bumps":
            texture.pixels = texture.pixels.copy()
            texture.pixels[..., 1] = 1.0 - texture.pixels[..., 1]
    return scene


def strength_zero(scene):
    """CONTROL: the Normal Map's strength 0 (the smooth normal)."""
    scene = copy.deepcopy(scene)
    for m in scene.materials:
        program = (m.programs or {}).get("normal")
        for node in (program.nodes if program is not None else ()):
            if node.kind == "ShaderNodeNormalMap":
                node.inputs["Strength"] = 0.0
    return scene


@pytest.fixture(scope="module")
def lit(tmp_path_factory):
    from tests.nodes import node_scene
    made = node_scene.ms.make("normal_map", str(tmp_path_factory.mktemp("normal_map")))
    return against_cycles(made, "normal_map")


def test_normal_map_sample_exports_a_normal_program(lit):
    exported, _ = lit
    assert exported.warnings == [], exported.warnings
    assert {m.name: sorted(m.programs) for m in exported.scene.materials if m.programs} == PROGRAMS
    ball = next(m for m in exported.scene.meshes if m.name == "Ball")
    assert ball.tangents is not None and set(np.unique(ball.tangent_signs)) <= {-1.0, 1.0}
    bumps = next(t for t in exported.scene.textures if t.name == "bumps")
    assert bumps.pixels.shape[:2] == (256, 256) and not bumps.is_srgb


def test_normal_map_sample_agrees_with_cycles(lit):
    exported, reference = lit
    result = compared(exported.scene, reference, "normal_map", png="normal_map")
    assert result.passed, result.summary()


def test_comparison_catches_the_green_channel_flipped(lit):
    exported, reference = lit
    result = compared(green_flipped(exported.scene), reference, "normal_map, green flipped", first_seed=2000)
    assert not result.passed, result.summary()


def test_comparison_catches_strength_zero(lit):
    exported, reference = lit
    result = compared(strength_zero(exported.scene), reference, "normal_map, strength 0", first_seed=3000)
    assert not result.passed, result.summary()


@pytest.fixture(scope="module")
def run34(tmp_path_factory):
    from blender34 import BLENDER34, blender34_run
    if BLENDER34 is None:
        pytest.skip("no `blender` binary (apt-get install blender)")
    r = blender34_run("normal_map", tmp_path_factory.mktemp("blender34"))
    assert r.blender[:2] == (3, 4)
    return r


def test_normal_map_sample_agrees_with_cycles_34(run34):
    from blender34 import tracer_runs
    from imagecompare import compare_runs
    assert run34.warnings == [], run34.warnings
    assert {m.name: sorted(m.programs) for m in run34.scene.materials if m.programs} == PROGRAMS
    assert type(next(m for m in run34.scene.materials if m.name == "NormalMapped").principled).__name__ == "PrincipledV1"
    result = compare_runs(tracer_runs(run34.scene), run34.cycles, tau=TAU)
    print(f"normal_map 3.4: {result.summary()}")
    assert result.passed, result.summary()


@pytest.mark.parametrize("control", [green_flipped, strength_zero], ids=["green flipped", "strength 0"])
def test_comparison_catches_a_wrong_normal_map_34(run34, control):
    from blender34 import tracer_runs
    from imagecompare import compare_runs
    result = compare_runs(tracer_runs(control(run34.scene), 2000), run34.cycles, tau=TAU)
    print(f"normal_map 3.4, {control.__name__}: {result.summary()}")
    assert not result.passed, result.summary()
