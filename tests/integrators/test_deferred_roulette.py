"""Russian roulette in Cycles' order (engine/integrators/path_tracer.py deferred_roulette): the effect
plan takes it for scenes of Cycles' material models only, it stays unbiased, and a roulette that
ends its paths before their ray's emission while dividing the survivors only after it is caught."""
import dataclasses

import numpy as np
import pytest

import engine.integrators.path_tracer
from engine import RenderSettings, render
from engine.integrators.effects import plan_effects
from engine.scene.model import GLOSSY, Material
from tests.integrators.test_estimator import Z, image_mean_and_se
from tests.scenes import diffuse_box_scene

SILENT = dict(log=lambda *a: None)


def glossy_box():
    """The small diffuse box with its red wall a Glossy BSDF (roughness 0.3)."""
    scene = diffuse_box_scene()
    mats = list(scene.materials)
    mats[1] = Material("Red glossy", GLOSSY, (0.7, 0.1, 0.1), roughness=0.3)
    return dataclasses.replace(scene, materials=mats)


def settings(**kw):
    return RenderSettings(**{"threads": 1, "tile_size": 16, "samples": 256, "max_depth": 12, **kw})


def test_the_plan_defers_the_roulette_for_cycles_materials_only():
    assert plan_effects(glossy_box(), RenderSettings()).enabled["deferred_roulette"]
    assert not plan_effects(diffuse_box_scene(), RenderSettings()).enabled["deferred_roulette"]
    assert not plan_effects(glossy_box(), RenderSettings(estimator="report")).enabled["deferred_roulette"]
    assert not plan_effects(glossy_box(), RenderSettings(russian_roulette=False)).enabled["deferred_roulette"]


def deferred_and_reference(**kw):
    """BSDF sampling alone (no shadow rays): every bit of light is emission that rays reach, what the
    deferred roulette counts before it ends a path."""
    on = render(glossy_box(), settings(rr_start_depth=1, shadow_rays=0, seed=1, **kw), **SILENT)
    off = render(glossy_box(), settings(russian_roulette=False, shadow_rays=0, seed=2, **kw), **SILENT)
    assert on.stats["effects"]["deferred_roulette"]
    return on, off


@pytest.mark.slow
def test_the_deferred_roulette_is_unbiased_and_shortens_paths():
    on, off = deferred_and_reference()
    (m_on, se_on), (m_off, se_off) = image_mean_and_se(on), image_mean_and_se(off)
    assert abs(m_on - m_off) < Z * np.hypot(se_on, se_off), (m_on, m_off, se_on, se_off)
    assert on.stats["rays"]["extension"] < 0.9 * off.stats["rays"]["extension"]


@pytest.mark.slow
def test_control_a_roulette_that_drops_the_emission_of_ended_rays_is_caught(monkeypatch):
    right = engine.integrators.path_tracer.PathTracer.deferred_roulette

    def dropping(self, beta, bounce, delta, u):
        keep, after = right(self, beta, bounce, delta, u)
        return keep & (after > 0.0), after      # ended at once; survivors still divided after their emission
    monkeypatch.setattr(engine.integrators.path_tracer.PathTracer, "deferred_roulette", dropping)
    on, off = deferred_and_reference(backend="numpy")        # (the compiled bounce has its own twin of it)
    (m_on, se_on), (m_off, se_off) = image_mean_and_se(on), image_mean_and_se(off)
    assert m_off - m_on > Z * np.hypot(se_on, se_off), (m_on, m_off, se_on, se_off)
