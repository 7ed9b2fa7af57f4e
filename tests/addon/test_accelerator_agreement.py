"""The octree and brute-force modes pass the same Cycles agreement test as Embree (issue: octree and
brute force selectable everywhere; "both pass the Cycles agreement test").

Kept small (the octree runs ~10^4 rays/s in Python): the diffuse room at 24x24, 16 spp.
"""
import pytest

from imagecompare import compare_runs, run_seeds
from rendering import cycles_runs, export_blend, tncg15_runs

RES = (24, 24)
SPP = 16
DEPTH = 4
K = 4


@pytest.fixture(scope="module")
def room_reference(samples):
    return cycles_runs(samples["diffuse_room"], RES, SPP, DEPTH, seeds=range(11, 11 + K))


@pytest.mark.slow          # 2-5 s (renders, subprocesses): make test-slow, which .ci/run runs too
@pytest.mark.parametrize("accelerator", ["octree", "embree"])
def test_accelerator_agrees_with_cycles(samples, room_reference, accelerator):
    scene = export_blend(samples["diffuse_room"], RES).scene
    ours = tncg15_runs(scene, SPP, DEPTH, seeds=run_seeds(500, K), accelerator=accelerator)
    result = compare_runs(ours, room_reference, tau=0.02)
    print(f"{accelerator}: {result.summary()}")
    assert result.passed, result.summary()


@pytest.mark.slow          # with its positive test above (its Cycles runs are this module's setup)
def test_accelerator_comparison_fails_on_a_wrong_scene(samples, room_reference):
    scene = export_blend(samples["diffuse_room"], RES).scene
    for m in scene.materials:
        m.emission = tuple(1.2 * e for e in m.emission)
    ours = tncg15_runs(scene, SPP, DEPTH, seeds=run_seeds(600, K), accelerator="octree")
    assert not compare_runs(ours, room_reference, tau=0.02).passed
