"""TNCG15 MC agrees with Cycles of the running Blender on Mix Shaders of different BSDFs
(engine/materials/mix.py, mcrt_addon/export/shader_mix.py): the sample scene "mix_shader" (balls of
Diffuse + Glossy mixed by a Layer Weight and by a Fresnel node, a Glass + Diffuse box at 0.5, a floor of
Diffuse + Glossy mixed by an image texture); and the comparison catches the old export (each mix
rendered as its first shader alone) and the texture factor ignored (its unlinked value).

Method and settings as tests/addon/test_agreement_materials.py: 64 x 64, 32 spp, max depth 8, K = 4
seeds each, 8 x 8 block means and the image mean within the Sidak-corrected z bound plus tau.
"""
import copy
import dataclasses

import pytest

from imagecompare import compare_runs
from rendering import RES, cycles_reference, export_blend, tncg15_agreement_runs

pytestmark = pytest.mark.slow
TAU = 0.02
NAME = "mix_shader"
_cache = {}


def exported(samples):
    if "res" not in _cache:
        _cache["res"] = export_blend(samples[NAME], RES)
    return _cache["res"]


def reference(samples):
    return cycles_reference(samples[NAME], NAME)


def ours(scene, first_seed=1000):
    return tncg15_agreement_runs(scene, first_seed)


def mixes(scene):
    return {m.name: m for m in scene.materials if m.kind == "mix"}


def test_mix_shader_scene_agrees_with_cycles(samples):
    res = exported(samples)
    assert res.warnings == [], res.warnings
    found = mixes(res.scene)
    assert sorted(found) == ["Checker mix", "Facing mix", "Fresnel mix", "Glass diffuse mix"], sorted(found)
    kinds = {name: [f.kind for leaf in m.mix.leaves for f in leaf.factors] for name, m in found.items()}
    assert kinds["Facing mix"] == ["layer_weight"] * 2 and kinds["Fresnel mix"] == ["fresnel"] * 2
    assert kinds["Checker mix"] == ["texture"] * 2 and kinds["Glass diffuse mix"] == ["constant"] * 2
    result = compare_runs(ours(res.scene), reference(samples), tau=TAU)
    print(f"{NAME}: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_each_mix_as_its_first_shader(samples):
    """Control: the old export of a mix of different BSDFs: one shader (here the first) at weight 1."""
    scene = copy.deepcopy(exported(samples).scene)
    for i, m in enumerate(scene.materials):
        if m.kind == "mix":
            scene.materials[i] = dataclasses.replace(m.mix.leaves[0].material, name=m.name, emission=m.emission)
    result = compare_runs(ours(scene, first_seed=2000), reference(samples), tau=TAU)
    print(f"{NAME}, first shader only: {result.summary()}")
    assert not result.passed, result.summary()


def test_comparison_catches_the_texture_factor_ignored(samples):
    """Control: the floor's checker factor replaced by the Mix node's unlinked factor (0.5)."""
    scene = copy.deepcopy(exported(samples).scene)
    for leaf in mixes(scene)["Checker mix"].mix.leaves:
        leaf.factors = [dataclasses.replace(f, kind="constant", value=0.5) for f in leaf.factors]
    result = compare_runs(ours(scene, first_seed=3000), reference(samples), tau=TAU)
    print(f"{NAME}, texture factor ignored: {result.summary()}")
    assert not result.passed, result.summary()
