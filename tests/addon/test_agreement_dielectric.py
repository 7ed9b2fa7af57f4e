"""TNCG15 MC agrees with Cycles of the running Blender on rough dielectrics (the rough_glass sample:
a Beckmann rough glass pane before a lit window, a multiscatter-GGX rough glass ball, a translucent
sheet lit from behind; engine/materials/dielectric.py, translucent.py), and the comparison catches
the old export (rough glass rendered smooth) and the single-scatter glass in place of Cycles'
compensated one.

Method and settings as tests/addon/test_agreement.py: 64 x 64, 32 spp, max depth 8, K = 4 seeds each,
8 x 8 block means and the image mean within the Sidak-corrected z bound plus tau.  Each test renders
Cycles (once per session) and K tracer runs: several seconds, so `make test-slow`.
"""
import copy

import pytest

from imagecompare import compare_runs
from rendering import RES, cycles_reference, export_blend, tncg15_agreement_runs

TAU = 0.02
pytestmark = pytest.mark.slow


def run(samples, scene, first_seed):
    result = compare_runs(tncg15_agreement_runs(scene, first_seed), cycles_reference(samples["rough_glass"],
                                                                                     "rough_glass"), tau=TAU)
    return result


def exported(samples):
    return copy.deepcopy(export_blend(samples["rough_glass"], RES).scene)


def test_rough_glass_agrees_with_cycles(samples):
    scene = exported(samples)
    kinds = {m.name: (m.kind, m.roughness, m.distribution) for m in scene.materials}
    assert kinds["Frosted"][0] == "glass" and kinds["Frosted"][2] == "multi_ggx" and kinds["Frosted"][1] > 0
    assert kinds["Ground glass"][2] == "beckmann" and kinds["Paper"][0] == "translucent"
    result = run(samples, scene, 1000)
    print(f"rough_glass: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_rough_glass_as_smooth(samples):
    """Control: the glass exported as before (roughness treated as 0: smooth glass)."""
    scene = exported(samples)
    for m in scene.materials:
        if m.kind == "glass":
            m.roughness = 0.0
    result = run(samples, scene, 2000)
    print(f"rough_glass as smooth: {result.summary()}")
    assert not result.passed, result.summary()


def test_comparison_catches_single_scatter_glass(samples):
    """Control: the multiscatter GGX ball rendered without Cycles 4.x's energy compensation."""
    scene = exported(samples)
    for m in scene.materials:
        if m.distribution == "multi_ggx":
            m.distribution = "ggx"
    result = run(samples, scene, 3000)
    print(f"rough_glass single scatter: {result.summary()}")
    assert not result.passed, result.summary()
