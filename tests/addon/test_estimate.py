"""mcrt_addon/estimate.py in process: the scene exported as F12 would (render border included),
a pilot on the render's own kind of workers, and the prediction of engine/rendering/estimate.py.
(The command line's `estimate` verb: tests/addon/test_stopping_addon.py.)"""
import bpy
import pytest

from mcrt_addon.estimate import DEFAULT_TARGET, estimate_scene
from rendering import open_blend


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_estimate_scene_predicts_for_the_border_at_the_panels_target(samples):
    scene = open_blend(samples["cornell"], (32, 24))
    scene.render.use_border = True
    scene.render.border_min_x, scene.render.border_max_x = 0.0, 0.5       # 16 x 24 pixels
    scene.render.border_min_y, scene.render.border_max_y = 0.0, 1.0
    scene.tncg15.samples = 256
    e = estimate_scene(scene, bpy.context.evaluated_depsgraph_get(), pilot_samples=8)
    assert e["resolution"] == [16, 24]
    assert e["target_rel_error"] == DEFAULT_TARGET                       # the panel's target is off
    assert e["samples_cap"] == 256 and 8 <= e["pilot_samples"] < 256 and e["pilot_seconds"] > 0
    assert e["seconds"] > 0 and e["mean_samples"] > 0
    scene.tncg15.use_noise_target, scene.tncg15.noise_target = True, 0.2
    again = estimate_scene(scene, bpy.context.evaluated_depsgraph_get(), pilot_samples=8)
    assert again["target_rel_error"] == pytest.approx(0.2)
