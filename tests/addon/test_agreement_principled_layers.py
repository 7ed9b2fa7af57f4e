"""TNCG15 MC agrees with Cycles of the running Blender on the Principled BSDF v2's layers
(engine/materials/principled.py): the principled_grid sample scene, Principled balls over roughness
in rows dielectric, metal, a tinted coat over white and sheen over dark blue; and the comparison
catches the coat ignored and the sheen ignored (what the exporter did before the layers).

Method and settings as tests/addon/test_agreement.py: 64 x 64, 32 spp, max depth 8, K = 4 seeds each,
8 x 8 block means and the image mean within the Sidak-corrected z bound plus tau.  Each test renders
ours 4 times (about 10 s on 2 cores): make test-slow.
"""
import copy

import bpy
import pytest

from imagecompare import compare_runs
from rendering import RES, cycles_reference, export_blend, tncg15_agreement_runs

TAU = 0.02
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(bpy.app.version < (4, 0, 0), reason="the Principled v2 layers are 4.0+")]


def exported(samples):
    return export_blend(samples["principled_grid"], RES)


def compare(samples, scene, first_seed):
    return compare_runs(tncg15_agreement_runs(scene, first_seed), cycles_reference(samples["principled_grid"]), tau=TAU)


def test_principled_grid_agrees_with_cycles(samples):
    ex = exported(samples)
    coated = [m.name for m in ex.scene.materials if m.principled is not None and m.principled.coat_weight > 0]
    sheened = [m.name for m in ex.scene.materials if m.principled is not None and m.principled.sheen_weight > 0]
    assert len(coated) == 4 and len(sheened) == 4, (coated, sheened)
    assert ex.warnings == [], ex.warnings
    result = compare(samples, ex.scene, 1000)
    print(f"principled_grid: {result.summary()}")
    assert result.passed, result.summary()


@pytest.mark.parametrize("layer", ["coat_weight", "sheen_weight"])
def test_comparison_catches_a_layer_ignored(samples, layer):
    """Controls: the coat (or the sheen) dropped, as the exporter did before."""
    scene = copy.deepcopy(exported(samples).scene)
    for m in scene.materials:
        if m.principled is not None:
            setattr(m.principled, layer, 0.0)
    result = compare(samples, scene, 2000)
    print(f"principled_grid without {layer}: {result.summary()}")
    assert not result.passed, result.summary()


@pytest.fixture(scope="module")
def veiled_grid(samples, tmp_path_factory):
    """principled_grid with Alpha 0.4 on the dielectric row (the back wall shows through them)."""
    from rendering import open_blend
    open_blend(samples["principled_grid"])
    for mat in bpy.data.materials:
        if mat.name.startswith("Dielectric"):
            node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
            node.inputs["Alpha"].default_value = 0.4
    path = str(tmp_path_factory.mktemp("veiled") / "principled_grid_alpha.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, check_existing=False)
    return path


def test_principled_alpha_agrees_with_cycles(veiled_grid):
    ex = export_blend(veiled_grid, RES)
    assert sorted(m.principled.alpha for m in ex.scene.materials if m.name.startswith("Dielectric")) == [0.4] * 4
    result = compare_runs(tncg15_agreement_runs(ex.scene, 3000), cycles_reference(veiled_grid), tau=TAU)
    print(f"principled_grid, alpha 0.4: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_alpha_ignored(veiled_grid):
    """Control: the dielectric row rendered opaque (alpha 1, as the exporter did before)."""
    scene = copy.deepcopy(export_blend(veiled_grid, RES).scene)
    for m in scene.materials:
        if m.principled is not None:
            m.principled.alpha = 1.0
    result = compare_runs(tncg15_agreement_runs(scene, 4000), cycles_reference(veiled_grid), tau=TAU)
    print(f"principled_grid, alpha 0.4 rendered opaque: {result.summary()}")
    assert not result.passed, result.summary()
