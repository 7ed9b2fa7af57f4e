"""TNCG15 MC agrees with Cycles of the running Blender on image textures on a float input and on a
tangent from the UV map (mcrt_addon/export/materials.py read_float, microfacet_nodes.py tangent_source):
the roughness_map sample (a Glossy plate with a checker roughness texture, an anisotropic ball whose
Tangent is a Tangent node in UV Map mode), and the same file with the ball's UV map turned by 90
degrees (the highlight turns across).  Controls that must fail: the texture ignored (the unlinked
roughness), the object's X axis as the tangent (the old export), the unturned UVs against the turned
file's Cycles.  The same file exported and rendered by Blender 3.4 (tests/addon/blender34.py) against
Cycles 3.4, with the texture and UV tangent ignored as its control.

Method and settings as tests/addon/test_agreement.py: 64 x 64, 32 spp, max depth 8, K = 4 seeds each,
8 x 8 block means and the image mean within the Sidak-corrected z bound plus tau.
"""
import copy

import bpy
import pytest

from imagecompare import compare_runs
from rendering import RES, cycles_reference, export_blend, open_blend, tncg15_agreement_runs

pytestmark = pytest.mark.slow          # Cycles references and K renders per test
TAU = 0.02


@pytest.fixture(scope="module")
def turned(samples, tmp_path_factory):
    """roughness_map with the ball's UV map turned by 90 degrees: (u, v) -> (v, -u)."""
    open_blend(samples["roughness_map"])
    layer = bpy.data.objects["Ball"].data.uv_layers["UVMap"]
    for loop in layer.data:
        u, v = loop.uv
        loop.uv = (v, -u)
    path = str(tmp_path_factory.mktemp("turned") / "roughness_map_turned.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True, check_existing=False)
    return path


def compare(scene, blend, name, first_seed):
    result = compare_runs(tncg15_agreement_runs(scene, first_seed), cycles_reference(blend, name), tau=TAU)
    print(f"{name}: {result.summary()}")
    return result


def test_roughness_map_agrees_with_cycles(samples):
    exported = export_blend(samples["roughness_map"], RES)
    by_name = {m.name: m for m in exported.scene.materials}
    assert "roughness" in by_name["Checker roughness"].input_textures
    assert by_name["Brushed"].tangent_source == "uv"
    result = compare(exported.scene, samples["roughness_map"], "roughness_map", 1000)
    assert result.passed, result.summary()


def test_turned_uv_map_agrees_with_cycles(turned):
    result = compare(export_blend(turned, RES).scene, turned, "roughness_map_turned", 1100)
    assert result.passed, result.summary()


def test_comparison_catches_the_roughness_texture_ignored(samples):
    """Control: the plate at its unlinked roughness (0.5) instead of the checker."""
    scene = copy.deepcopy(export_blend(samples["roughness_map"], RES).scene)
    for m in scene.materials:
        m.input_textures = {}
    result = compare(scene, samples["roughness_map"], "roughness_map", 2000)
    assert not result.passed, result.summary()


def test_comparison_catches_the_object_x_tangent(turned):
    """Control: the ball's tangent the object's X axis (the export before UV tangents)."""
    scene = copy.deepcopy(export_blend(turned, RES).scene)
    for m in scene.materials:
        m.tangent_source = "fixed"
    result = compare(scene, turned, "roughness_map_turned", 3000)
    assert not result.passed, result.summary()


def test_comparison_catches_the_unturned_uv_map(samples, turned):
    """Control: the original file's tangents against the turned file's Cycles."""
    result = compare(export_blend(samples["roughness_map"], RES).scene, turned, "roughness_map_turned", 4000)
    assert not result.passed, result.summary()


# -- Blender 3.4 (tests/addon/blender34.py: its exporter, its Cycles; the scene through a scene file) ---------
def blender34_roughness_map(tmp_path_factory):
    from blender34 import BLENDER34, blender34_run
    if BLENDER34 is None:
        pytest.skip("no `blender` binary (apt-get install blender)")
    r = blender34_run("roughness_map", tmp_path_factory.mktemp("blender34"))
    assert r.blender[:2] == (3, 4) and r.warnings == [], r.warnings
    return r


def test_roughness_map_agrees_with_cycles_34(tmp_path_factory):
    from blender34 import tracer_runs
    r = blender34_roughness_map(tmp_path_factory)
    by_name = {m.name: m for m in r.scene.materials}
    assert "roughness" in by_name["Checker roughness"].input_textures and by_name["Brushed"].tangent_source == "uv"
    result = compare_runs(tracer_runs(r.scene), r.cycles, tau=TAU)
    print(f"roughness_map 3.4: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_the_texture_ignored_34(tmp_path_factory):
    from blender34 import tracer_runs
    scene = copy.deepcopy(blender34_roughness_map(tmp_path_factory).scene)
    for m in scene.materials:
        m.input_textures, m.tangent_source = {}, "fixed"
    result = compare_runs(tracer_runs(scene, 2000), blender34_roughness_map(tmp_path_factory).cycles, tau=TAU)
    print(f"roughness_map 3.4, texture and UV tangent ignored: {result.summary()}")
    assert not result.passed, result.summary()
