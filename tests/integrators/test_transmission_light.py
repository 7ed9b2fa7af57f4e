"""Light through non-delta transmission lobes (engine/integrators/path_tracer.py direct_light): a
translucent sheet and a rough glass pane seen from below, lit only by a lamp above them.  Light
samples from the far side, BSDF samples alone and the report's estimator give the same image.
Control: without far-side light samples the MIS image loses the light-sample half."""
import numpy as np
import pytest

import engine.integrators.path_tracer
from engine import RenderSettings, render
from engine.scene.model import DIFFUSE, GLASS, TRANSLUCENT, TRANSPARENT, Camera, Material, Quad, Scene

SILENT = dict(log=lambda *a: None)


def sheet_scene(kind, roughness=None):
    """Camera under a 2 x 2 m sheet at z = 0 looking up; a 1 m lamp at z = 1 above it."""
    extra = {} if roughness is None else {"roughness": roughness}
    materials = [Material("Sheet", kind, (0.8, 0.8, 0.8), ior=1.5, **extra),
                 Material("Lamp", DIFFUSE, (0.0, 0.0, 0.0), emission=(5.0, 5.0, 5.0))]

    def square(half, z, mat):
        return Quad(f"q{mat}", np.array([(-half, -half, z), (half, -half, z), (half, half, z), (-half, half, z)]), mat)
    camera = Camera.look_at((0.0, 0.0, -1.5), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), lens=30.0)
    return Scene(camera, materials, [], [], [square(1.0, 0.0, 0), square(0.5, 1.0, 1)], resolution=(16, 16),
                 name="sheet")


def image(scene, **kw):
    settings = RenderSettings(samples=64, seed=5, threads=1, parallelism="threads", **kw)
    return render(scene, settings, **SILENT).image[..., :3]


@pytest.mark.parametrize("kind, roughness", [(TRANSLUCENT, None), (GLASS, 0.4)])
def test_light_from_the_far_side_agrees_across_estimators(kind, roughness):
    scene = sheet_scene(kind, roughness)
    mis = image(scene).mean()
    bsdf_only = image(scene, shadow_rays=0).mean()
    report = image(scene, estimator="report").mean()
    assert mis > 0.02
    assert abs(bsdf_only / mis - 1.0) < 0.05 and abs(report / mis - 1.0) < 0.05


def test_control_without_far_side_light_samples_the_image_darkens(monkeypatch):
    scene = sheet_scene(TRANSLUCENT)
    mis = image(scene).mean()
    monkeypatch.setattr(engine.integrators.path_tracer, "transmits_non_delta", lambda flags: False)
    assert image(scene).mean() < 0.8 * mis


def test_transparent_sheet_shows_the_lamp_behind_it():
    """A colour-0.8 transparent sheet passes the lamp's radiance times 0.8 (delta: weight 1 beyond it)."""
    scene = sheet_scene(TRANSPARENT)
    img = image(scene)
    centre = img[7:9, 7:9].mean()
    assert abs(centre - 0.8 * 5.0) < 1e-3


def test_effect_plan_names_the_dielectric_lobes():
    from engine.integrators.effects import plan_effects
    rough = plan_effects(sheet_scene(GLASS, 0.4), RenderSettings())
    assert rough.enabled["rough_glass"] and not rough.enabled["glass"] and rough.enabled["direct_light"]
    assert "visible normals" in rough.reason["rough_glass"] and "both sides" in rough.reason["rough_glass"]
    smooth = plan_effects(sheet_scene(GLASS), RenderSettings())
    assert smooth.enabled["glass"] and not smooth.enabled["rough_glass"] and not smooth.enabled["direct_light"]
    sheet = plan_effects(sheet_scene(TRANSLUCENT), RenderSettings())
    assert sheet.enabled["translucent"] and "far side" in sheet.reason["translucent"] and sheet.enabled["direct_light"]
    veil = plan_effects(sheet_scene(TRANSPARENT), RenderSettings())
    assert veil.enabled["transparent"] and "block shadow rays" in veil.reason["transparent"]
