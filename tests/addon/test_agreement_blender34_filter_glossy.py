"""Filter Glossy on Blender 3.4's Principled BSDF v1 agrees with Cycles 3.4 (tests/addon/blender34.py):
the glossy_plates scene with its Glossy plates replaced by sharp Principled metal (roughness 0.05,
GGX) in Blender 3.4, whose caustics on the diffuse room (hits of the plates after a diffuse bounce)
Filter Glossy 1.0 spreads (Cycles 3.4's bsdf_blur, docs/cycles34-filter-glossy.md;
engine/materials/principled_v1.py).  Control that must fail: the tracer without Filter Glossy
against the same references (the v1 before Filter Glossy reached it renders so: the scene's other
materials are diffuse)."""
import os

import pytest

from blender34 import BLENDER34, blender34_run, tracer_runs
from imagecompare import compare_runs
from engine.materials.table import PRINCIPLED_V1, scatter_kind

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(BLENDER34 is None and os.environ.get("CI") != "true",
                                 reason="no `blender` binary (apt-get install blender)")]
TAU = 0.02                  # the agreement tests' model-difference budget (tests/addon/test_agreement_materials.py)
FILTER = dict(filter_glossy=1.0)


@pytest.fixture(scope="module")
def plates(tmp_path_factory):
    r = blender34_run("glossy_plates", tmp_path_factory.mktemp("blender34_filter_glossy"),
                      edit="sharp_principled_plates", light_paths=FILTER)
    assert r.blender[:2] == (3, 4) and r.scene.cycles_version == (3, 4)
    metal = [m for m in r.scene.materials if scatter_kind(m) == PRINCIPLED_V1]
    assert len(metal) == 4 and all(m.principled.metallic == 1.0 and m.roughness == pytest.approx(0.05)
                                   for m in metal), metal
    return r


def test_filter_glossy_on_sharp_principled_v1_agrees_with_cycles_34(plates):
    result = compare_runs(tracer_runs(plates.scene, **FILTER), plates.cycles, tau=TAU)
    print(f"sharp v1 plates, Filter Glossy 1: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_filter_glossy_left_out(plates):
    result = compare_runs(tracer_runs(plates.scene, first_seed=2000), plates.cycles, tau=TAU)
    print(f"sharp v1 plates, Filter Glossy left out: {result.summary()}")
    assert not result.passed, result.summary()
