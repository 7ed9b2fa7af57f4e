"""Sample .blend files moved 5e5 units away (every object's transform, the offset in the matrix and the
vertices local, as a user's scene far from the origin) render as at the origin, through the exporter:
meshes, implicit spheres, Area, point, spot and sun lights (engine/scene/tracing_origin.py; the
engine-level test with 1e5 to 1e6 is tests/rendering/test_far_from_origin.py)."""
import bpy
import numpy as np
import pytest

from imagecompare import compare_runs, run_seeds
from rendering import export_blend, tncg15_runs

RES, SPP, K, DEPTH = (32, 32), 16, 4, 8
OFFSET = 5e5
BLENDS = ["cornell", "area_light", "point_light", "spot_light", "sun_window"]


GRID = 1 / 32        # float32's spacing from 2**18 to 2**19 (262,144 to 524,288)


def moved_export(blend, offset):
    """The .blend exported with every top-level object moved by `offset` along each axis.  Blender keeps
    locations in float32, so 5e5 + 0.1 would round to 500000.09375: the objects' locations are first
    snapped to the grid that float32 holds exactly at 5e5 (in both scenes), so the scene moved is the
    same scene, and only the tracer's rounding can tell them apart."""
    export_blend(blend, RES)                                  # opens it
    for ob in bpy.data.objects:
        if ob.parent is None:
            ob.location = tuple(round(c / GRID) * GRID + offset for c in ob.location)
    bpy.context.view_layer.update()
    from tests.addon.exporting import export
    return export(RES)


def runs(exported, first_seed):
    return tncg15_runs(exported.scene, SPP, DEPTH, seeds=run_seeds(first_seed, K))


@pytest.mark.slow       # 12 renders per scene (about 2 s each scene)
@pytest.mark.parametrize("name", BLENDS)
def test_a_sample_blend_far_from_the_origin_renders_as_at_the_origin(samples, name):
    origin = runs(moved_export(samples[name], 0.0), 1)
    far_scene = moved_export(samples[name], OFFSET)
    assert np.abs(far_scene.scene.camera.matrix[:3, 3]).min() > 4e5
    result = compare_runs(runs(far_scene, 101), origin, tau=0.0)
    assert result.passed, result.summary()
    same_seed = runs(far_scene, 1)[0]                          # the origin's paths, but for rounding
    assert (np.abs(same_seed - origin[0]).max(axis=-1) > 1e-4).mean() < 0.01


@pytest.mark.slow
def test_control_traced_in_world_coordinates_the_far_room_fails(samples, monkeypatch):
    """CONTROL: with the tracing origin at the world origin (as before), the comparison fails."""
    import engine.rendering.session as session
    origin = runs(moved_export(samples["area_light"], 0.0), 1)
    monkeypatch.setattr(session, "tracing_origin", lambda scene: None)
    far = runs(moved_export(samples["area_light"], OFFSET), 101)
    assert not compare_runs(far, origin, tau=0.0).passed
