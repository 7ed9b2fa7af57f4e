"""The Principled BSDF v2's layers over its base (engine/materials/principled.py: alpha, sheen, coat;
engine/materials/sheen.py): the protocol's contract, χ² of the layered sampler, white furnaces (a coat
over white diffuse at most 1, a tinted coat's absorption), the sheen's albedo against the values of
Cycles' table, alpha's pass-through, the scene model and file, the effect plan, and a render where an
alpha-0 ball vanishes; each with a control that fails (a pdf without the sheen, the coat not darkening
the base, the pass-through not a delta bounce)."""
import json

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.core.errors import SceneError
from engine.integrators.effects import plan_effects
from engine.materials import principled as principled_module
from engine.materials import sheen
from engine.materials.principled import PASS_LOBE, PrincipledV2
from engine.materials.protocol import BSDFFlags
from engine.scene.files import load_scene, save_scene
from engine.scene.model import DIFFUSE, PRINCIPLED, AreaLight, Camera, Material, PointLight, Principled, Quad, Scene, Sphere
from tests.chi_square import ALPHA, sphere_chi2
from tests.integrators.test_mis import block_test
from tests.materials.test_bsdf_contract import hits as random_hits
from tests.materials.test_bsdf_contract import sample_matches_eval
from tests.materials.test_principled import hits, incidence

# Cycles' table_sheen_ltc (its src/scene/shader.tables, commit 97dbe6f57), the albedo block at
# roughness 16/31: (mu, R) at mu = 31/31, 16/31, 3/31.
CYCLES_SHEEN_ALBEDO = ((1.0, 0.02208), (16 / 31, 0.15718), (3 / 31, 0.56229))


def layered(color=(1.0, 1.0, 1.0), roughness=0.5, metallic=0.0, level=0.5, **layers):
    return Material("L", PRINCIPLED, color, roughness=roughness,
                    principled=Principled(metallic=metallic, specular_ior_level=level, **layers))


def furnace(m, mu, color=(1.0, 1.0, 1.0), n=50_000, seed=5):
    """(mean (3,), standard error of red) of the sampled values: the directional albedo at mu."""
    bsdf = PrincipledV2([m], None)
    rng = np.random.default_rng(seed)
    s = bsdf.sample(hits(incidence(mu), n, color), rng.random(n), (rng.random(n), rng.random(n)))
    return s.value.mean(axis=1), float(s.value[0].std() / np.sqrt(n))


# -- the protocol --------------------------------------------------------------------------------------
@pytest.mark.parametrize("layers", [dict(coat_weight=1.0), dict(sheen_weight=1.0, sheen_tint=(1.0, 0.5, 0.2)),
                                    dict(alpha=0.6, coat_weight=0.5, coat_tint=(0.9, 0.6, 0.3), sheen_weight=0.7)])
@pytest.mark.parametrize("metallic", [0.0, 0.6])
def test_layered_sample_agrees_with_eval_and_pdf(layers, metallic):
    m = layered((0.9, 0.5, 0.2), 0.4, metallic, coat_roughness=0.2, **layers)
    bsdf = PrincipledV2([m], None)
    assert bsdf.any_layers
    assert sample_matches_eval(bsdf, random_hits(11, color=(0.9, 0.5, 0.2)), 11)


def test_flags_name_the_pass_through_only_with_alpha():
    assert PrincipledV2([layered(coat_weight=1.0)], None).flags == principled_module.FLAGS
    assert PrincipledV2([layered(alpha=0.5)], None).flags == principled_module.FLAGS | PASS_LOBE
    assert not PrincipledV2([layered()], None).any_layers           # no layer: the base alone, as before


# -- χ² ---------------------------------------------------------------------------------------------------
def layered_sampler(bsdf, wo, color=(0.8, 0.6, 0.4)):
    def sample(u):
        n = u.shape[1]
        s = bsdf.sample(hits(wo, n, color), np.random.default_rng(17).random(n), (u[0], u[1]))
        return np.where((s.pdf > 0) & ((s.flags & BSDFFlags.DELTA) == 0), s.wi, 0.0)   # the delta mass counts nowhere

    def pdf(d):
        return bsdf.pdf(hits(wo, d.shape[1], color), d)
    return sample, pdf


@pytest.mark.parametrize("mu", [0.3])
def test_layered_sampler_matches_its_pdf(mu):
    m = layered((0.8, 0.6, 0.4), 0.5, 0.3, coat_weight=0.8, coat_roughness=0.25, sheen_weight=1.0,
                sheen_roughness=0.6, alpha=0.8)
    sample, pdf = layered_sampler(PrincipledV2([m], None), incidence(mu))
    p, dof = sphere_chi2(sample, pdf, n=100_000, z_bins=32, phi_bins=64, seed=7)
    assert dof > 50 and p > ALPHA, (p, dof)


def test_chi2_rejects_a_layered_pdf_without_the_sheen():
    """Control: the pdf the mixture would have without the sheen lobe's share."""
    m = layered((0.8, 0.6, 0.4), 0.5, 0.0, sheen_weight=1.0, sheen_roughness=0.6)
    bsdf = PrincipledV2([m], None)
    sample, _ = layered_sampler(bsdf, incidence(0.3))

    def without_sheen(d):
        si = hits(incidence(0.3), d.shape[1], (0.8, 0.6, 0.4))
        layers, weights, prob = bsdf._layered_lobes(si)
        weights[0] = np.zeros_like(weights[0])
        return bsdf._layered_mixture(si, d, layers, weights, prob)[1]
    assert sphere_chi2(sample, without_sheen, n=100_000, z_bins=32, phi_bins=64, seed=7)[0] < 1e-6


# -- the sheen's albedo ---------------------------------------------------------------------------------
@pytest.mark.parametrize("mu,cycles", CYCLES_SHEEN_ALBEDO)
def test_sheen_albedo_is_cycles_table(mu, cycles):
    """The lobe alone (black base, no specular): its albedo by sampling and by integrating eval over
    the hemisphere both read Cycles' table value (the LTC is a normalised density)."""
    m = layered((0.0, 0.0, 0.0), level=0.0, sheen_weight=1.0, sheen_roughness=16 / 31)
    value, _ = furnace(m, mu, color=(0.0, 0.0, 0.0), n=5_000)
    assert abs(value[0] - cycles) < 1e-4, (value, cycles)
    k = 200                                                     # midpoint rule in (cos, phi)
    c = (np.arange(k) + 0.5) / k
    phi = (np.arange(2 * k) + 0.5) / (2 * k) * 2 * np.pi
    cc, pp = np.meshgrid(c, phi, indexing="ij")
    s = np.sqrt(1 - cc * cc)
    wi = np.stack([s * np.cos(pp), s * np.sin(pp), cc]).reshape(3, -1)
    bsdf = PrincipledV2([m], None)
    f_cos = bsdf.eval(hits(incidence(mu), wi.shape[1], (0.0, 0.0, 0.0)), wi)[0][0]
    assert abs(f_cos.sum() * (1.0 / k) * (np.pi / k) - cycles) < 2e-3 * max(cycles, 0.1)


def test_sheen_table_layout_and_cutoff():
    a, b, r = sheen.table()
    assert a.shape == b.shape == r.shape == (32, 32)
    assert abs(r[16, 31] - 0.02208) < 1e-5 and abs(r[16, 3] - 0.56229) < 1e-5    # [roughness row, mu column]
    assert sheen.sheen_albedo(np.array([0.5]), np.array([0.0]))[0] == 0.0         # no lobe at roughness 0


@pytest.mark.parametrize("mu", [1.0, 0.5, 0.1])
def test_white_furnace_sheen_over_white_diffuse_reads_one(mu):
    """R + (1 - R) x 1: the sheen darkens the diffuse by exactly its albedo."""
    value, err = furnace(layered(level=0.0, sheen_weight=1.0, sheen_roughness=0.5), mu)
    assert abs(value[0] - 1.0) < 4 * err + 1e-3, (value, err)


# -- the coat ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("coat_roughness", [0.03, 0.3])
@pytest.mark.parametrize("mu", [1.0, 0.5, 0.1])
def test_white_furnace_coat_over_white_diffuse_at_most_one(mu, coat_roughness):
    value, err = furnace(layered(level=0.0, coat_weight=1.0, coat_roughness=coat_roughness), mu)
    assert 0.97 < value[0] <= 1.0 + 4 * err + 2e-3, (value, err)


def test_furnace_control_coat_not_darkening_the_base_exceeds_one(monkeypatch):
    """Control: the base at weight W regardless of the coat (no closure_layering_weight)."""
    real = PrincipledV2.layer_weights

    def undarkened(self, si):
        layers = real(self, si)
        layers.base = np.ones_like(layers.base)
        return layers
    monkeypatch.setattr(PrincipledV2, "layer_weights", undarkened)
    value, err = furnace(layered(level=0.0, coat_weight=1.0, coat_roughness=0.03), 0.1)
    assert value[0] > 1.1, value


@pytest.mark.parametrize("mu", [1.0, 0.5])
def test_coat_tint_absorbs_along_the_refracted_path(mu):
    """White diffuse under a tinted coat: A_coat + (1 - A_coat) tint^(1 / cos_t) (Cycles' closure.h)."""
    tint = np.array([1.0, 0.5, 0.25])
    value, err = furnace(layered(level=0.0, coat_weight=1.0, coat_roughness=0.3, coat_tint=tuple(tint)), mu)
    untinted, _ = furnace(layered(level=0.0, coat_weight=1.0, coat_roughness=0.3), mu)
    bsdf = PrincipledV2([layered(level=0.0, coat_weight=1.0, coat_roughness=0.3)], None)
    a_coat = bsdf.layer_weights(hits(incidence(mu), 1)).coat_albedo[0]
    cos_t = np.sqrt(1 - (1 - mu * mu) / 1.5 ** 2)
    expected = untinted[0] - (1 - a_coat) * (1 - tint ** (1 / cos_t))
    assert np.allclose(value, expected, atol=4 * err + 2e-3), (value, expected)


# -- alpha -------------------------------------------------------------------------------------------------
def test_alpha_passes_straight_through_with_probability_one_minus_alpha():
    n, alpha = 50_000, 0.3
    bsdf = PrincipledV2([layered((0.8, 0.8, 0.8), alpha=alpha)], None)
    wo = incidence(0.6)
    rng = np.random.default_rng(4)
    s = bsdf.sample(hits(wo, n, (0.8, 0.8, 0.8)), rng.random(n), (rng.random(n), rng.random(n)))
    through = s.flags == int(PASS_LOBE)
    assert abs(through.mean() - (1 - alpha)) < 4 * np.sqrt(alpha * (1 - alpha) / n)
    assert np.allclose(s.wi[:, through], -wo[:, None]) and np.all(s.value[:, through] == 1.0)
    opaque, _ = furnace(layered((0.8, 0.8, 0.8)), 0.6, color=(0.8, 0.8, 0.8), n=n, seed=4)
    non_delta = np.where(through, 0.0, s.value[0]).mean()
    assert abs(non_delta - alpha * opaque[0]) < 0.01, (non_delta, alpha * opaque[0])


# -- the scene model, the file and the plan -----------------------------------------------------------------
def test_validation_names_the_material_and_the_layer():
    for bad in (dict(coat_ior=0.9), dict(alpha=1.5), dict(sheen_roughness=-0.1), dict(coat_tint=(1.0, -1.0, 0.0))):
        m = layered(**bad)
        m.name = "Varnish"
        with pytest.raises(SceneError, match="Material 'Varnish'.*(coat_ior|alpha|sheen_roughness|coat_tint)"):
            m.validate()


def small_scene(**layers):
    mats = [layered((0.8, 0.5, 0.3), 0.35, **layers), Material("Floor", DIFFUSE, (0.5, 0.5, 0.5)),
            Material("Light", DIFFUSE, (0, 0, 0), emission=(6.0, 6.0, 6.0))]
    big, s = 4.0, 0.4
    floor = Quad("Floor", np.array([(-big, -big, 0), (big, -big, 0), (big, big, 0), (-big, big, 0)], float), 1)
    light = Quad("Light", np.array([(-s, -s, 2.0), (-s, s, 2.0), (s, s, 2.0), (s, -s, 2.0)], float), 2)
    ball = Sphere("Ball", np.array([0.0, 0.0, 0.5]), 0.5, 0)
    cam = Camera.look_at((0.0, -2.5, 1.2), (0.0, 0.0, 0.5), up=(0, 0, 1), lens=40.0)
    return Scene(cam, mats, spheres=[ball], quads=[floor, light], resolution=(16, 16))


def test_scene_file_round_trip_of_the_layers(tmp_path):
    layers = dict(coat_weight=0.7, coat_roughness=0.1, coat_ior=1.6, coat_tint=(1.0, 0.9, 0.8), sheen_weight=0.4,
                  sheen_roughness=0.3, sheen_tint=(0.5, 0.6, 0.7), alpha=0.9, transmission_weight=0.2)
    path = str(tmp_path / "p.json")
    save_scene(small_scene(**layers), path)
    again = load_scene(path).materials[0].principled
    assert again == Principled(**layers)
    save_scene(small_scene(), path)                              # no layer: the file is as before
    assert set(json.load(open(path))["materials"][0]["principled"]) == {"metallic", "specular_ior_level", "specular_tint"}
    assert load_scene(path).materials[0].principled == Principled()


def test_transmission_weight_is_modelled_without_a_warning():
    assert not any("transmission" in w for w in small_scene(transmission_weight=0.3).validate())


def test_effect_plan_names_the_layers_and_sees_lamps_through_alpha():
    reason = plan_effects(small_scene(coat_weight=1.0, sheen_weight=0.5, alpha=0.5), RenderSettings()).reason
    assert "'L' alpha pass-through + sheen (microfiber) + coat (GGX) + specular (GGX) + diffuse" in reason["principled"]
    for alpha, seen in ((0.5, True), (1.0, False)):         # a round lamp behind an alpha surface is met by rays
        scene = small_scene(alpha=alpha)
        scene.points = [PointLight("Bulb", (0.0, 1.5, 1.5), (3.0, 3.0, 3.0), radius=0.25)]
        assert plan_effects(scene, RenderSettings()).enabled["seen_lamps"] == seen


# -- a render: an alpha-0 ball is not there ----------------------------------------------------------------
def lamp_scene(ball=True):
    """The alpha-0 ball on the floor under a 1.6 m square lamp: the floor under it is lit only by
    the pass-through rays (its shadow rays stop at the ball), often enough to converge."""
    scene = small_scene(alpha=0.0)
    s = 0.8
    scene.quads[1].corners = np.array([(-s, -s, 2.0), (-s, s, 2.0), (s, s, 2.0), (s, -s, 2.0)], float)
    scene.materials[2].emission = (3.0, 3.0, 3.0)
    if not ball:
        scene.spheres = []
    return scene


def ball_vanishes(scene, seed):
    common = dict(threads=1, tile_size=16, max_depth=6, samples=384, estimator="mis")
    a = render(scene, RenderSettings(seed=seed, **common), log=lambda *x: None)
    b = render(lamp_scene(ball=False), RenderSettings(seed=seed + 1, **common), log=lambda *x: None)
    assert np.isfinite(a.image).all() and a.stats["nonfinite_samples"] == 0
    z, z_crit = block_test(a, b, block=4)
    return z < z_crit, (z, z_crit)


def test_an_alpha_zero_ball_renders_as_no_ball():
    """Shadow rays stop at the ball, but the pass-through rays' delta bounce counts the light they
    reach fully: the floor under the ball is lit as if it were not there."""
    ok, figures = ball_vanishes(lamp_scene(), seed=1)
    assert ok, figures


def test_control_a_pass_through_weighed_by_mis_darkens_the_shadow(monkeypatch):
    """Control: the pass-through flagged as non-delta transmission: the emission behind it is
    MIS-weighed against shadow rays that the ball blocks, and the ball's shadow stays."""
    monkeypatch.setattr(principled_module, "PASS_LOBE", BSDFFlags.TRANSMISSION)
    ok, figures = ball_vanishes(lamp_scene(), seed=1)
    assert not ok, figures


def veil_before_a_lamp():
    """An Area light facing the camera (invisible to camera rays, Cycles' default) behind an
    alpha-0 ball that fills the view."""
    lamp = AreaLight("Lamp", np.array([(-1.0, 2.0, -1.0), (1.0, 2.0, -1.0), (1.0, 2.0, 1.0), (-1.0, 2.0, 1.0)], float),
                     (5.0, 5.0, 5.0), two_sided=True)
    cam = Camera.look_at((0.0, -2.0, 0.0), (0.0, 0.0, 0.0), up=(0, 0, 1), lens=50.0)
    return Scene(cam, [layered(alpha=0.0)], spheres=[Sphere("Veil", np.array([0.0, 0.0, 0.0]), 1.2, 0)],
                 lights=[lamp], resolution=(8, 8))


def test_camera_rays_through_alpha_stay_camera_rays():
    """The lamp is not seen through the ball, as Cycles' transparent bounce keeps the camera ray."""
    image = render(veil_before_a_lamp(), RenderSettings(samples=4, threads=1, max_depth=4), log=lambda *x: None).image
    assert image.max() == 0.0


def test_control_a_pass_through_as_glass_refraction_shows_the_lamp(monkeypatch):
    monkeypatch.setattr(principled_module, "PASS_LOBE", BSDFFlags.TRANSMISSION | BSDFFlags.DELTA)
    image = render(veil_before_a_lamp(), RenderSettings(samples=4, threads=1, max_depth=4), log=lambda *x: None).image
    assert image.mean() > 1.0
