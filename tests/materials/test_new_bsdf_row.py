"""A BSDF that is not Lambertian reaches the integrator through eval and pdf alone.

`EvalLambertian` is the Lambertian BSDF without `lambert_albedo`: put in the material table's
row for diffuse materials (what a new BSDF such as GGX is: one class and one row), the direct-light
stage weighs each shadow ray by its eval (f cos) instead of multiplying rho / pi in after the
mean, MIS takes its pdf, and the direct light (float64) and the image (float32) are the Lambertian
ones up to rounding.  Control: an eval that drops the cosine gives another image."""
import numpy as np
import pytest

import engine.materials.table
from engine import RenderSettings, render
from engine.materials.lambert import Lambertian
from engine.scene.builtin import cornell_scene

SILENT = dict(log=lambda *a: None)


class EvalLambertian(Lambertian):
    evals = 0

    def lambert_albedo(self, si):
        return None

    def eval(self, si, wi):
        EvalLambertian.evals += 1
        return super().eval(si, wi)


class NoCosine(EvalLambertian):
    def eval(self, si, wi):
        f_cos, pdf = super().eval(si, wi)
        return np.where(pdf > 0.0, si.color * (1.0 / np.pi), 0.0), pdf


def render_with(monkeypatch, diffuse_bsdf, **kw):
    rows = [(kind, diffuse_bsdf if bsdf is Lambertian else bsdf) for kind, bsdf in engine.materials.table.SCATTERING]
    with monkeypatch.context() as m:
        m.setattr(engine.materials.table, "SCATTERING", tuple(rows))
        settings = RenderSettings(samples=4, seed=3, threads=1, parallelism="threads", **kw)
        return render(cornell_scene((24, 24)), settings, **SILENT).image


@pytest.mark.parametrize("kw", [dict(estimator="mis"), dict(estimator="mis", shadow_rays=3),
                                dict(estimator="solid-angle")], ids=["mis", "mis-3-rays", "solid-angle"])
def test_a_bsdf_seen_through_eval_renders_the_lambertian_image(monkeypatch, kw):
    reference = render_with(monkeypatch, Lambertian, **kw)
    EvalLambertian.evals = 0
    through_eval = render_with(monkeypatch, EvalLambertian, **kw)
    assert EvalLambertian.evals > 0
    assert np.allclose(through_eval, reference, rtol=1e-6, atol=1e-9)      # a few float32 steps
    assert reference.mean() > 0.01


@pytest.mark.parametrize("shadow_rays", [1, 4])
def test_direct_light_through_eval_is_the_lambertian_estimate(shadow_rays):
    from engine.geometry.scene_geometry import Counters
    from engine.materials.protocol import ShadingPoint
    from engine.rendering.session import PreparedScene
    tracer = PreparedScene(cornell_scene((8, 8)), RenderSettings(shadow_rays=shadow_rays), **SILENT).tracer
    n = 5000
    rng = np.random.default_rng(4)
    point = np.stack([rng.uniform(-0.9, 0.9, n), rng.uniform(-0.9, 0.9, n), np.full(n, 1e-3)])  # the floor
    up = np.tile([[0.0], [0.0], [1.0]], (1, n))
    hit = ShadingPoint(up, up, up, up, np.tile([[0.7], [0.5], [0.3]], (1, n)), np.zeros(n, dtype=np.int64))
    u = tuple(np.random.default_rng(5).random((3, n * shadow_rays)))
    lambert = tracer.direct_light(Lambertian([], tracer.settings), hit, point, np.full(n, 1e-6), None, Counters(), u=u)
    through_eval = tracer.direct_light(EvalLambertian([], tracer.settings), hit, point, np.full(n, 1e-6), None,
                                       Counters(), u=u)
    assert (lambert > 0).mean() > 0.5
    assert np.allclose(through_eval, lambert, rtol=1e-12, atol=0)


def test_an_eval_without_the_cosine_is_seen(monkeypatch):
    reference = render_with(monkeypatch, Lambertian, estimator="mis")
    wrong = render_with(monkeypatch, NoCosine, estimator="mis")
    assert np.abs(wrong - reference).max() > 1e-3
