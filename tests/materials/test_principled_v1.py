"""Blender 3.4's Principled BSDF v1 (engine/materials/principled_v1.py): the protocol's contract, χ²
of the mixed closure sampler at several roughness / metallic / clearcoat / sheen, Burley's diffuse
and the interpolated Fresnel against hand-computed values, GTR1's normalisation, the multiscatter
approximation's white furnace, the scatter row chosen by the dataclass, the scene file and the
effect plan; each statistical check with a control that fails (a mixture pdf without the diffuse
closure, the single-scatter lobe in the furnace)."""
import json

import numpy as np
import pytest

from engine import RenderSettings
from engine.integrators.effects import plan_effects
from engine.materials.principled_v1 import (PrincipledV1, burley_diffuse, gtr1_d, gtr1_sample,
                                            interpolated_fresnel, specular_ior)
from engine.materials.protocol import ShadingPoint
from engine.materials.table import KIND_CODE, PRINCIPLED, PRINCIPLED_V1, MaterialTable, scatter_kind
from engine.scene.files import load_scene, save_scene
from engine.scene.model import Material, Principled, PrincipledV1 as Inputs
from tests.chi_square import ALPHA, sphere_chi2
from tests.materials.test_bsdf_contract import hits as random_hits, reciprocal, sample_matches_eval

NORMAL = np.array([0.0, 0.0, 1.0])


def v1(roughness=0.5, color=(0.8, 0.6, 0.4), multiscatter=False, anisotropy=0.0, **inputs):
    return Material("P34", PRINCIPLED, color, roughness=roughness, multiscatter=multiscatter,
                    anisotropy=anisotropy, principled=Inputs(**inputs))


def incidence(mu, phi=0.3):
    s = np.sqrt(1.0 - mu * mu)
    return np.array([s * np.cos(phi), s * np.sin(phi), mu])


def hits(wo, n, color=(0.8, 0.6, 0.4)):
    def tile(v):
        return np.tile(np.asarray(v, dtype=np.float64)[:, None], (1, n))
    return ShadingPoint(tile(wo), tile(NORMAL), tile(NORMAL), tile(NORMAL), tile(color), np.zeros(n, dtype=np.int64))


CASES = {"default": {}, "metal": dict(metallic=1.0, roughness=0.25),
         "clearcoat-sheen": dict(metallic=0.3, clearcoat=1.0, clearcoat_roughness=0.3, sheen=1.0, roughness=0.3),
         "multiscatter": dict(metallic=0.5, multiscatter=True), "anisotropic": dict(anisotropy=0.7, clearcoat=0.5),
         "tinted": dict(specular=1.0, specular_tint=1.0, sheen=0.5, sheen_tint=1.0, roughness=0.8)}


@pytest.mark.parametrize("case", sorted(CASES))
def test_sample_agrees_with_eval_and_pdf(case):
    bsdf = PrincipledV1([v1(**CASES[case])], RenderSettings())
    assert sample_matches_eval(bsdf, random_hits(11), seed=3)


@pytest.mark.parametrize("case", ["default", "metal", "clearcoat-sheen", "tinted"])
def test_single_scatter_closures_are_reciprocal(case):
    assert reciprocal(PrincipledV1([v1(**CASES[case])], RenderSettings()), seed=4)


# -- χ² of the mixed sampler ---------------------------------------------------------------------------
def mixed(bsdf, wo, pdf_of=None):
    def sample(u):
        n = u.shape[1]
        s = bsdf.sample(hits(wo, n), np.random.default_rng(17).random(n), (u[0], u[1]))
        return np.where(s.pdf > 0, s.wi, 0.0)

    def pdf(d):
        return (pdf_of or bsdf.pdf)(hits(wo, d.shape[1]), d)
    return sample, pdf


@pytest.mark.parametrize("roughness,metallic,clearcoat", [(0.25, 0.0, 0.0), (0.5, 1.0, 0.0), (0.5, 0.0, 1.0),
                                                          (1.0, 0.5, 1.0)])
def test_mixed_sampler_matches_its_pdf(roughness, metallic, clearcoat):
    bsdf = PrincipledV1([v1(roughness, metallic=metallic, clearcoat=clearcoat, clearcoat_roughness=0.25,
                            sheen=0.5)], RenderSettings())
    p, dof = sphere_chi2(*mixed(bsdf, incidence(0.6)), n=100_000, z_bins=32, phi_bins=64, seed=7)
    assert dof > 50 and p > ALPHA, (p, dof)


def test_chi2_rejects_a_mixture_pdf_without_the_diffuse_closure():
    bsdf = PrincipledV1([v1(0.25)], RenderSettings())

    def specular_only(si, d):
        weights, prob = bsdf.closures(si)
        weights = [np.zeros_like(weights[0]), weights[1], weights[2], weights[3]]
        return bsdf._mixture(si, si.wo, d, weights, prob)[1] / np.maximum(prob[2], 1e-300)
    assert sphere_chi2(*mixed(bsdf, incidence(0.6), specular_only), n=100_000, z_bins=32, phi_bins=64,
                       seed=7)[0] < 1e-6


# -- hand-computed values --------------------------------------------------------------------------------
def test_burley_diffuse_against_a_hand_computed_value():
    """cos_o = 0.5, cos_i = 0.8, wo.wi = 0.3, roughness 0.5: F_o = 0.5^5 = 0.03125, F_i = 0.2^5 = 0.00032,
    R = 0.5 x 1.3 = 0.65; f = (1 - 0.015625)(1 - 0.00016) + 0.65 (0.03157 + 0.00001 x (-0.35))
    = 0.9842175 + 0.65 x 0.0315665 = 1.004735725."""
    fo, fi, rr = 0.03125, 0.00032, 0.65
    f = (1 - fo / 2) * (1 - fi / 2) + rr * (fo + fi + fo * fi * (rr - 1))
    assert f == pytest.approx(1.004735725, abs=1e-12)
    assert burley_diffuse(np.array([0.5]), np.array([0.8]), np.array([0.3]), np.array([0.5]))[0] == \
        pytest.approx(0.8 / np.pi * f, rel=1e-12)
    # roughness 0 at normal incidence both ways: Lambert, f cos = cos / pi
    assert burley_diffuse(np.array([1.0]), np.array([1.0]), np.array([1.0]), np.array([0.0]))[0] == \
        pytest.approx(1.0 / np.pi, rel=1e-12)


def test_the_specular_closure_as_closure_h_sets_it_up():
    """Specular 0.5: eta = 2 / (1 - sqrt(0.04)) - 1 = 1.5, F0 = 0.04; cspec0 = 0.08 x specular x tint
    mixed to the base colour by metallic; the interpolated Fresnel is cspec0 at normal incidence, 1 at grazing."""
    assert specular_ior(0.5) == pytest.approx(1.5)
    bsdf = PrincipledV1([v1(metallic=0.25, specular_tint=1.0, color=(0.8, 0.4, 0.2))], RenderSettings())
    si = hits(NORMAL, 1, (0.8, 0.4, 0.2))
    lum = 0.3 * 0.8 + 0.6 * 0.4 + 0.1 * 0.2
    expected = 0.04 * np.array([0.8, 0.4, 0.2]) / lum * 0.75 + np.array([0.8, 0.4, 0.2]) * 0.25
    assert np.allclose(bsdf.cspec0(si)[:, 0], expected, rtol=1e-12)
    cspec0 = np.full((3, 1), 0.3)
    assert np.allclose(interpolated_fresnel(np.ones(1), np.full(1, 1.5), cspec0), 0.3)
    assert np.allclose(interpolated_fresnel(np.zeros(1), np.full(1, 1.5), cspec0), 1.0)


@pytest.mark.parametrize("alpha", [0.01, 0.09, 0.5])
def test_gtr1_is_normalised_and_its_sampler_draws_it(alpha):
    z = (np.arange(200_000) + 0.5) / 200_000
    assert (gtr1_d(z, np.full(z.size, alpha)) * z).mean() * 2 * np.pi == pytest.approx(1.0, rel=2e-3)
    rng = np.random.default_rng(3)
    h = gtr1_sample(np.full(50_000, alpha), rng.random(50_000), rng.random(50_000))
    # mean of cos_h under D cos: compare with the quadrature
    mean_quad = (gtr1_d(z, np.full(z.size, alpha)) * z * z).mean() * 2 * np.pi
    assert h[2].mean() == pytest.approx(mean_quad, abs=4 * h[2].std() / np.sqrt(50_000))


def furnace(bsdf, mu, n=200_000, seed=5):
    rng = np.random.default_rng(seed)
    s = bsdf.sample(hits(incidence(mu), n, (1.0, 1.0, 1.0)), rng.random(n), (rng.random(n), rng.random(n)))
    return float(s.value[0].mean()), float(s.value[0].std() / np.sqrt(n))


@pytest.mark.parametrize("mu", [0.2, 0.7])
def test_multiscatter_approximation_keeps_a_white_metal_white(mu):
    """"Multiscatter GGX" (roughness 1, white metal) reflects what it receives, as Heitz's random walk;
    the control, the node's "GGX" (single scatter, separable G), reads 0.51 and 0.36."""
    multi, err = furnace(PrincipledV1([v1(1.0, metallic=1.0, multiscatter=True)], RenderSettings()), mu)
    assert abs(multi - 1.0) < 0.01 + 4 * err, (multi, err)
    single, _ = furnace(PrincipledV1([v1(1.0, metallic=1.0)], RenderSettings()), mu)
    assert single < 0.7


# -- the model and its row -------------------------------------------------------------------------------
def test_the_dataclass_chooses_the_row():
    m34, m50 = v1(), Material("P50", PRINCIPLED, principled=Principled())
    assert scatter_kind(m34) == PRINCIPLED_V1 and scatter_kind(m50) == PRINCIPLED
    assert scatter_kind(Material("Pnone", PRINCIPLED)) == PRINCIPLED
    black = v1(color=(0.0, 0.0, 0.0))
    table = MaterialTable([m34, m50, black], RenderSettings())
    assert list(table.scatter_group) == [KIND_CODE[PRINCIPLED_V1], KIND_CODE[PRINCIPLED], KIND_CODE[PRINCIPLED_V1]]
    assert table.glossy and isinstance(table.bsdfs[KIND_CODE[PRINCIPLED_V1]], PrincipledV1)


def test_validation_names_the_material():
    from engine.core.errors import SceneError
    with pytest.raises(SceneError, match="'P34'.*sheen"):
        v1(sheen=-1.0).validate()
    v1(clearcoat=1.0, sheen=1.0).validate()


def small_scene(**inputs):
    from tests.materials.test_principled import small_scene as v2_scene
    scene = v2_scene()
    scene.materials[0] = v1(0.35, **inputs)
    scene.cycles_version = (3, 4)
    return scene


def test_scene_file_round_trip(tmp_path):
    scene = small_scene(metallic=0.3, sheen=0.5, clearcoat=1.0, clearcoat_roughness=0.1, specular_tint=0.2)
    path = str(tmp_path / "p.json")
    save_scene(scene, path)
    data = json.load(open(path))
    assert data["cycles_version"] == [3, 4] and data["materials"][0]["principled_v1"]["clearcoat"] == 1.0
    again = load_scene(path)
    assert again.materials[0].principled == scene.materials[0].principled
    assert scatter_kind(again.materials[0]) == PRINCIPLED_V1 and again.cycles_version == (3, 4)


def test_effect_plan_names_the_v1_closures():
    plan = plan_effects(small_scene(sheen=0.5, clearcoat=1.0), RenderSettings())
    assert plan.enabled["principled"]
    assert "'P34' diffuse (Burley, v1) + sheen + specular (GGX) + clearcoat (GTR1)" in plan.reason["principled"]
