"""Caustic photons in whole renders (slow): no light counted twice, and a bias that falls as passes
accumulate against a path-traced reference (engine/integrators/photons/, engine/integrators/path_tracer.py)."""
from __future__ import annotations

import numpy as np
import pytest

import engine.integrators.path_tracer as path_tracer_module
from engine.api import render
from engine.core.settings import RenderSettings
from engine.scene.builtin import caustic_scene
from tests.integrators.photons.scenes import glass_ball_room

pytestmark = pytest.mark.slow


def means(scene, seeds, **settings):
    return np.array([render(scene, RenderSettings(seed=s, **settings)).image.mean() for s in seeds])


def double_count_z(scene, double=False, monkeypatch=None):
    """z of the image mean with photons against path tracing alone (seeds as independent runs)."""
    if double:          # control: the path tracer keeps the paths the photons own
        monkeypatch.setattr(path_tracer_module.PathTracer, "photons_own",
                            staticmethod(lambda p, idx: np.zeros(len(idx), dtype=bool)))
    path = means(scene, range(4), samples=256, caustics_method="path")
    photons = means(scene, range(10, 14), samples=64, caustics_method="photons", photons_per_pass=20_000)
    se = np.sqrt(path.var(ddof=1) / len(path) + photons.var(ddof=1) / len(photons))
    return (photons.mean() - path.mean()) / se, photons.mean() / path.mean() - 1.0


def test_photons_and_paths_count_each_path_once():
    """A room with a glass ball under a large lamp, where path tracing alone converges: the same mean
    with the photon map on (|z| < 4), and within 1 %."""
    z, rel = double_count_z(glass_ball_room((16, 16)))
    assert abs(z) < 4 and abs(rel) < 0.01, (z, rel)


def test_control_counting_the_caustics_twice_fails(monkeypatch):
    z, rel = double_count_z(glass_ball_room((16, 16)), double=True, monkeypatch=monkeypatch)
    assert z > 4, (z, rel)


def block_error(image, reference, region):
    """The RMS relative error of the 4 x 4-pixel block means that lie mostly (3/4) in `region`."""
    h, w = reference.shape[:2]
    a = image.mean(axis=2).reshape(h // 4, 4, w // 4, 4).mean(axis=(1, 3))
    b = reference.mean(axis=2).reshape(h // 4, 4, w // 4, 4).mean(axis=(1, 3))
    m = (region.reshape(h // 4, 4, w // 4, 4).mean(axis=(1, 3)) >= 0.75) & (b > 0)
    return float(np.sqrt(np.mean((a[m] / b[m] - 1.0) ** 2)))


def test_the_caustics_bias_falls_as_passes_accumulate():
    """The glass ball on the floor under a small lamp: the caustic's block error against a path-traced
    reference (its own noise about 1.5 % a block) falls from 4 to 64 passes (the fitted exponent is
    negative) and ends below 5 %, where path tracing at 64 samples is far off."""
    scene = caustic_scene((32, 32))
    reference = render(scene, RenderSettings(samples=8192, caustics_method="path", seed=7)).image
    path_few = render(scene, RenderSettings(samples=64, caustics_method="path", seed=1)).image
    bright = reference.mean(axis=2) > 2.0 * np.median(reference.mean(axis=2))
    region = bright.copy()
    region[:16] = False                                   # the floor under the ball, not the lamp
    errors = {n: block_error(render(scene, RenderSettings(samples=n, caustics_method="photons", seed=1,
                                                         photons_per_pass=20_000)).image, reference, region)
              for n in (4, 16, 64)}
    slope = np.polyfit(np.log(list(errors)), np.log(list(errors.values())), 1)[0]
    assert slope < 0 and errors[64] < errors[4] and errors[64] < 0.05, (errors, slope)
    assert block_error(path_few, reference, region) > errors[64]         # what the photons beat
