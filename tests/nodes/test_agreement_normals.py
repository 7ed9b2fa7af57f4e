"""TNCG15 MC agrees with Cycles 5.0 on a lit scene whose BSDFs' Normal inputs are node graphs
(tests/nodes/normal_scene.py: a Normal Map in tangent space on a smooth UV sphere, a Bump of a Noise
Texture on the floor), and the comparison catches a flipped bitangent sign and an inverted bump.

Method as tests/addon/test_agreement_materials.py: 64 x 64, 32 spp, max depth 8, K = 4 seeds each."""
import copy

import numpy as np
import pytest

from tests.nodes.agreement import TAU, against_cycles, compared

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def lit(tmp_path_factory):
    from tests.nodes import normal_scene
    return against_cycles(normal_scene.build(str(tmp_path_factory.mktemp("normals") / "normals.blend")), "normals")


def test_normal_inputs_export_as_normal_programs_with_tangents(lit):
    exported, _ = lit
    programs = {m.name: sorted(m.programs) for m in exported.scene.materials if m.programs}
    assert programs == {"NormalBall": ["normal"], "BumpFloor": ["normal"]}
    assert not exported.warnings, exported.warnings
    ball = next(m for m in exported.scene.meshes if m.name == "Sphere")
    assert ball.tangents is not None and ball.tangent_signs is not None
    assert set(np.unique(ball.tangent_signs)) <= {-1.0, 1.0}


def test_normal_map_and_bump_agree_with_cycles(lit):
    exported, reference = lit
    result = compared(exported.scene, reference, "normals", png="normals")
    assert result.passed, result.summary()


def test_comparison_catches_a_flipped_bitangent_sign(lit):
    exported, reference = lit
    scene = copy.deepcopy(exported.scene)
    for mesh in scene.meshes:
        if mesh.tangent_signs is not None:
            mesh.tangent_signs = -mesh.tangent_signs
    result = compared(scene, reference, "normals, bitangent sign flipped", first_seed=2000)
    assert not result.passed, result.summary()


def test_comparison_catches_an_inverted_bump(lit):
    exported, reference = lit
    scene = copy.deepcopy(exported.scene)
    floor = next(m for m in scene.materials if m.name == "BumpFloor")
    next(n for n in floor.programs["normal"].nodes if n.kind == "ShaderNodeBump").props["invert"] = True
    result = compared(scene, reference, "normals, bump inverted", first_seed=3000)
    assert not result.passed, result.summary()


def test_normals_facing_away_agree_with_cycles(tmp_path_factory):
    """The Wave Texture's colour itself into the Normal Map: its dark bands (colour ~0) give normals
    pointing into the ball, which Cycles' Diffuse keeps and its bump shadowing term darkens."""
    from imagecompare import compare_runs, run_seeds
    from rendering import DEPTH, K, SPP, tncg15_runs
    from tests.nodes import normal_scene
    exported, reference = against_cycles(
        normal_scene.build(str(tmp_path_factory.mktemp("normals") / "away.blend"), facing_away=True),
        "normals_facing_away")
    result = compared(exported.scene, reference, "normals facing away")
    assert result.passed, result.summary()
    scene = copy.deepcopy(exported.scene)          # CONTROL: without the bump shadowing term
    from engine.integrators.path_tracer import PathTracer
    saved = PathTracer.bump_shadowing              # the one entry on both backends (numba: normals_jit)
    try:
        PathTracer.bump_shadowing = lambda self, si, wi, *a, **k: np.ones(wi.shape[1])
        ours = tncg15_runs(scene, SPP, DEPTH, seeds=run_seeds(2000, K), fresnel="exact", threads=1)   # in-process
        control = compare_runs(ours, reference, tau=TAU)
    finally:
        PathTracer.bump_shadowing = saved
    print(f"normals facing away, no bump shadowing: {control.summary()}")
    assert not control.passed, control.summary()


@pytest.fixture(scope="module")
def run34(tmp_path_factory):
    from blender34 import BLENDER34, blender34_run
    if BLENDER34 is None:
        pytest.skip("no `blender` binary (apt-get install blender)")
    r = blender34_run("normals", tmp_path_factory.mktemp("blender34"))
    assert r.blender[:2] == (3, 4)
    return r


def test_normal_map_and_bump_agree_with_cycles_34(run34):
    from blender34 import tracer_runs
    from imagecompare import compare_runs
    assert run34.warnings == [], run34.warnings
    assert {m.name: sorted(m.programs) for m in run34.scene.materials if m.programs} == {
        "NormalBall": ["normal"], "BumpFloor": ["normal"]}
    result = compare_runs(tracer_runs(run34.scene), run34.cycles, tau=TAU)
    print(f"normals 3.4: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_a_flipped_bitangent_sign_34(run34):
    from blender34 import tracer_runs
    from imagecompare import compare_runs
    scene = copy.deepcopy(run34.scene)
    for mesh in scene.meshes:
        if mesh.tangent_signs is not None:
            mesh.tangent_signs = -mesh.tangent_signs
    result = compare_runs(tracer_runs(scene, 2000), run34.cycles, tau=TAU)
    print(f"normals 3.4, bitangent sign flipped: {result.summary()}")
    assert not result.passed, result.summary()
