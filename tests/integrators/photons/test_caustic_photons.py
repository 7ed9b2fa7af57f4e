"""The caustic photon pass (engine/integrators/photons/): emission, tracing, the density estimate,
the radius schedule, the pass's determinism, and the effect plan that switches it on."""
from __future__ import annotations

import numpy as np
import pytest

import engine.integrators.photons.caustics as caustics_module
import engine.integrators.photons.emission as emission_module
from engine.core.settings import RenderSettings
from engine.geometry.scene_geometry import Counters
from engine.integrators.effects import plan_effects
from engine.integrators.photons.caustics import CausticPhotons, auto_radius
from engine.integrators.photons.emission import emit, light_flux
from engine.integrators.photons.photon_map import radius_of_pass
from engine.integrators.photons.targets import specular_targets
from engine.integrators.photons.tracing import trace_photons
from engine.lights.aim import SphereTargets
from engine.materials.lambert import Lambertian
from engine.materials.protocol import ShadingPoint
from engine.rendering.session import PreparedScene
from engine.scene.builtin import caustic_scene, cornell_scene
from tests.integrators.photons.scenes import CEILING_Z, diffuse_only, mirror_under_ceiling, mirrored_irradiance


def prepared(scene, **settings):
    return PreparedScene(scene, RenderSettings(caustics_method="photons", **settings), log=lambda *a: None)


def ceiling_irradiance(photons, points, passes):
    """The photon map's irradiance estimate at ceiling points (rows), averaged over passes 0..passes-1:
    the radiance of a white Lambertian ceiling (colour 1) times pi."""
    m = points.shape[1]
    down = np.tile([[0.0], [0.0], [-1.0]], (1, m))
    si = ShadingPoint(down.copy(), down.copy(), down.copy(), down.copy(), np.ones((3, m)), np.zeros(m, np.int64),
                      False, None, None)
    total = np.zeros(m)
    for k in range(passes):
        total += np.pi * photons.map_of(k, Counters()).radiance(Lambertian([], None), si, points, down)[0]
    return total / passes


def ceiling_points(half=0.5, n=15):
    g = np.linspace(-half, half, n)
    x, y = np.meshgrid(g, g)
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, CEILING_Z)])


def mirror_error(scale=1.0, monkeypatch=None):
    if monkeypatch is not None:
        real = emission_module.emit

        def scaled(*a, **k):
            e = real(*a, **k)
            e.flux = e.flux * scale
            return e
        monkeypatch.setattr(caustics_module, "emit", scaled)
    photons = prepared(mirror_under_ceiling(), photons_per_pass=60_000, photon_radius=0.05, seed=3).tracer.photons
    points = ceiling_points()
    estimate = ceiling_irradiance(photons, points, 8)      # one batch of passes
    return estimate.mean() / mirrored_irradiance(points).mean() - 1.0


def test_the_ceiling_gets_the_mirrored_lamps_irradiance():
    """R I cos(theta) / d^2 from the lamp's image, within 2 %, over a patch of the ceiling."""
    assert abs(mirror_error()) < 0.02


def test_control_a_photon_weight_off_by_five_percent_fails(monkeypatch):
    assert abs(mirror_error(1.05, monkeypatch)) > 0.02


def test_path_tracing_alone_sees_no_mirrored_point_light():
    """The same scene without photons: the ceiling gets the lamp's direct light only (its image in
    the mirror is a delta light no path can reach); with photons it gets the mirrored light too."""
    from engine.api import render
    scene = mirror_under_ceiling((4, 4))
    common = dict(samples=4, max_depth=2, seed=1)
    path = render(scene, RenderSettings(caustics_method="path", **common)).image.mean()
    photons = render(scene, RenderSettings(caustics_method="photons", photons_per_pass=20_000, **common)).image.mean()
    assert photons > path * 1.1


# -- emission --------------------------------------------------------------------------------
def test_the_photons_flux_sums_to_the_lights_power():
    """Unaimed, the photons' flux sums to the lights' flux; aimed at the glass ball, to the flux of the
    unaimed photons whose rays meet the ball."""
    lights = prepared(caustic_scene((8, 8))).lights
    rng = np.random.default_rng(2)
    e = emit(lights, 400_000, rng)
    assert e.flux.mean(axis=0).sum() == pytest.approx(light_flux(lights).sum(), rel=0.01)
    ball = SphereTargets([[0.0], [0.0], [0.35]], [0.35])
    rel = ball.center - e.origin
    along = (rel * e.direction).sum(axis=0)
    meets = (along > 0) & ((rel * rel).sum(axis=0) - along ** 2 <= 0.35 ** 2)
    aimed = emit(lights, 400_000, rng, ball)
    assert aimed.flux.mean(axis=0).sum() == pytest.approx(e.flux[:, meets].mean(axis=0).sum(), rel=0.02)
    assert not (aimed.flux.mean(axis=0).sum() == pytest.approx(e.flux.mean(axis=0).sum(), rel=0.3))


def test_aimed_photons_are_mostly_caustic():
    """Aimed at the ball, most photons are stored (they reach the floor through the glass)."""
    p = prepared(caustic_scene((8, 8)))
    photons = p.tracer.photons
    e = emit(p.lights, 20_000, np.random.default_rng(0), photons.targets)
    stored = trace_photons(p.tracer, e.origin, e.direction, e.flux, Counters(), np.random.default_rng(1), 8)
    assert stored.flux.shape[1] > 0.8 * e.emitted
    assert (stored.position[2] < 1.0).mean() > 0.9                         # on the floor, mostly


# -- passes -------------------------------------------------------------------------------------
def test_a_pass_is_a_function_of_the_seed_and_its_number():
    a = prepared(caustic_scene((8, 8)), photons_per_pass=2000).tracer.photons
    b = prepared(caustic_scene((8, 8)), photons_per_pass=2000).tracer.photons
    b.map_of(3, Counters())
    for k in (0, 3):
        assert np.array_equal(a.map_of(k, Counters()).position, b.map_of(k, Counters()).position)
    assert not np.array_equal(a.map_of(0, Counters()).position, a.map_of(1, Counters()).position)


def test_the_radius_shrinks_as_sppm():
    r = [radius_of_pass(1.0, k, 2 / 3) for k in range(200)]
    step = [r[0] ** 2]
    for i in range(1, 200):
        step.append(step[-1] * (i + 2 / 3) / (i + 1))
    assert np.allclose(np.square(r), step, rtol=1e-12)
    assert r[199] ** 2 == pytest.approx(r[99] ** 2 * 2 ** (-1 / 3), rel=0.01)      # r^2 ~ k^(alpha - 1)


def test_the_auto_radius_follows_the_pixel_footprint():
    scene = caustic_scene((96, 96))
    p = prepared(scene)
    small = auto_radius(scene, p.tracer.photons.targets)
    scene.resolution = (192, 192)
    assert auto_radius(scene, p.tracer.photons.targets) == pytest.approx(small / 2)
    assert isinstance(p.tracer.photons, CausticPhotons) and p.tracer.photons.first_radius == small


# -- the effect plan -----------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["auto", "photons"])
def test_no_photon_pass_without_specular_surfaces(method):
    plan = plan_effects(diffuse_only(), RenderSettings(caustics_method=method))
    assert not plan.photon_caustics and "no specular surface" in plan.reason["photon_caustics"]
    assert prepared(diffuse_only()).tracer.photons is None


def test_the_photon_pass_runs_where_asked_and_useful():
    on = plan_effects(cornell_scene((8, 8)), RenderSettings(caustics_method="auto"))
    assert on.photon_caustics and "'Glass'" in on.reason["photon_caustics"]
    off = plan_effects(cornell_scene((8, 8)), RenderSettings(caustics_method="path"))
    assert not off.photon_caustics and "path tracing alone" in off.reason["photon_caustics"]
    toggled = plan_effects(cornell_scene((8, 8)), RenderSettings(caustics_method="photons", caustics_refractive=False))
    assert not toggled.photon_caustics and "leave caustics out" in toggled.reason["photon_caustics"]


def test_auto_traces_photons_but_the_report_estimator_and_clamping_keep_path_tracing():
    # the default stays path tracing until the Cycles agreement suites pass with auto (docs/photons.md)
    assert RenderSettings().caustics_method == "path"
    assert not plan_effects(cornell_scene((8, 8)), RenderSettings()).photon_caustics
    assert plan_effects(cornell_scene((8, 8)), RenderSettings(caustics_method="auto")).photon_caustics
    report = plan_effects(cornell_scene((8, 8)), RenderSettings(estimator="report", caustics_method="auto"))
    assert not report.photon_caustics and "report estimator" in report.reason["photon_caustics"]
    clamped = plan_effects(cornell_scene((8, 8)), RenderSettings(clamp_indirect=10.0, caustics_method="auto"))
    assert not clamped.photon_caustics and "clamping on" in clamped.reason["photon_caustics"]
    assert plan_effects(cornell_scene((8, 8)), RenderSettings(clamp_indirect=10.0, caustics_method="photons")).photon_caustics


def test_a_photons_chain_counts_its_bounces_but_the_first():
    """Through the glass ball: two refractions, of which the chain counts the second (the camera
    path's last bounce may pass its type's limit); the budget of a diffuse receiver is the limits
    less the camera's bounces and its own (engine/integrators/light_paths.py chain_budget)."""
    from engine.integrators.light_paths import LightPaths
    from engine.materials.protocol import BSDFFlags
    p = prepared(caustic_scene((8, 8)))
    e = emit(p.lights, 2000, np.random.default_rng(0), p.tracer.photons.targets)
    stored = trace_photons(p.tracer, e.origin, e.direction, e.flux, Counters(), np.random.default_rng(1), 8)
    through = stored.segments == 3                          # light -> glass -> glass -> floor
    assert through.mean() > 0.5 and (stored.chain[:, through] == [[0], [1], [0]]).all()
    settings = RenderSettings(diffuse_bounces=2, glossy_bounces=3, transmission_bounces=1, transparent_bounces=8)
    lp = LightPaths(settings, plan_effects(caustic_scene((8, 8)), settings), p.tracer.bsdfs)
    counts = np.array([[0, 1, 2], [0, 2, 0], [0, 0, 1], [0, 0, 0]])
    budget = lp.chain_budget(counts, BSDFFlags.DIFFUSE | BSDFFlags.REFLECTION)
    assert budget.tolist() == [[3, 1, -1], [1, 1, -1], [7, 7, -1]]     # the third: its diffuse bounce is past 2


def test_the_targets_hold_every_specular_object():
    scene = cornell_scene((8, 8))
    t = specular_targets(scene, prepared(scene).tracer.mats)
    assert t.count == 2 and np.allclose(sorted(t.radius), [0.3, 0.35])


def test_the_image_is_the_same_on_every_pool():
    """Each pass's batch is traced once, by whichever worker is free, and shared
    (engine/rendering/photon_passes.py): one thread, two threads and two forked processes give the
    same image bit for bit, each tracing the one batch once."""
    from engine.api import render
    scene = caustic_scene((32, 16))
    runs = [render(scene, RenderSettings(samples=3, caustics_method="photons", photons_per_pass=3000, threads=t,
                                         parallelism=kind))
            for kind, t in (("threads", 1), ("threads", 2), ("processes", 2))]
    images = [r.image for r in runs]
    assert np.array_equal(images[0], images[1]) and np.array_equal(images[0], images[2])
    assert images[0].sum() > 0
    assert all(r.stats["photons"]["photon_passes_traced"] == 8 for r in runs)


def test_photons_leave_a_mesh_lamp():
    """A lamp of emissive triangles (as Blender files have them) does not stop its own photons."""
    from engine.scene.builtin import box_wall
    scene = caustic_scene((8, 8))
    lamp = next(q for q in scene.quads if scene.materials[q.material_id].is_emissive)
    scene.quads.remove(lamp)
    scene.meshes.append(box_wall("Lamp mesh", lamp.corners, lamp.material_id))
    photons = prepared(scene, photons_per_pass=5000).tracer.photons
    assert photons.map_of(0, Counters()).count > 0.8 * 5000


def test_the_stats_count_the_photon_passes():
    from engine.api import render
    r = render(caustic_scene((16, 16)), RenderSettings(samples=3, caustics_method="photons", photons_per_pass=1000,
                                                       threads=1))
    ph = r.stats["photons"]
    assert ph["photon_passes"] == 8 and ph["photon_passes_traced"] == 8          # one batch, one worker
    assert ph["photons_emitted"] == 8000 and 0 < ph["photons_stored"] <= ph["photons_traced"] <= 8000
    assert ph["radius_last"] < ph["radius_first"] and ph["gather_seconds"] > 0
    assert "photons" not in render(caustic_scene((16, 16)), RenderSettings(samples=1, threads=1, caustics_method="path")).stats


@pytest.mark.parametrize("kind, flux", [("suns", lambda k: np.pi * 0.25 * k.radiance[:, 0]),
                                        ("world", lambda k: 4 * np.pi * np.pi * 0.25 * k.radiance[:, 0])])
def test_lights_at_infinity_aim_at_a_target_disk(kind, flux):
    """A delta sun's photons aimed at a sphere of radius 0.5 carry E pi r^2 between them; the world's,
    L 4 pi pi r^2 (the flux through the sphere's cross-section), and every ray meets the sphere."""
    from tests.lights import kinds as K
    light = getattr(K, kind)()
    ball = SphereTargets([[0.2], [0.1], [0.3]], [0.5])
    rng = np.random.default_rng(4)
    n = 20000
    e = light.sample_emission(np.zeros(n, np.int64), *rng.random((4, n)), targets=ball)
    phi = e.radiance * np.abs((e.direction * e.normal).sum(axis=0)) / (e.pdf_pos * e.pdf_dir)
    assert np.allclose(phi.mean(axis=1), flux(light), rtol=1e-9)
    rel = ball.center - e.origin
    along = (rel * e.direction).sum(axis=0)
    assert ((rel * rel).sum(axis=0) - along ** 2 <= 0.25 * (1 + 1e-9)).all() and (along > 0).all()


class _FlatMaps:
    """A batch's photon maps whose radiance is 1 at every point they are asked about (and count them)."""
    passes = tuple(range(8))
    radius = np.ones(16)

    def __init__(self):
        self.asked = 0

    def radiance(self, bsdf, si, points, facing, local, radius, segments, budget, kernels):
        self.asked += points.shape[1]
        return np.ones((3, points.shape[1]))


def _secondary_gather(monkeypatch, q, m=20000):
    monkeypatch.setattr(caustics_module, "SECONDARY_GATHER", q)
    photons = CausticPhotons.__new__(CausticPhotons)
    photons.settings = RenderSettings(seed=3)
    photons.kernels = None
    flat = _FlatMaps()
    photons.maps_of = lambda b, counters, cancel=None: flat
    points = np.random.default_rng(1).random((3, m))
    si = ShadingPoint(*(np.zeros((3, m)) for _ in range(5)), np.zeros(m, np.int64), False, None, None)
    secondary = np.arange(m) % 2 == 1
    out = photons.radiance(np.zeros(m, np.int64), None, si, points, points, Counters(), secondary=secondary)
    return out[0], secondary, flat.asked


@pytest.mark.parametrize("q", [0.25, 1.0])
def test_vertices_after_a_diffuse_bounce_gather_with_probability_q_and_weight_one_over_q(monkeypatch, q):
    out, secondary, asked = _secondary_gather(monkeypatch, q)
    assert np.all(out[~secondary] == 1.0)                                  # first vertices: always, weight 1
    assert set(np.unique(out[secondary])) <= {0.0, 1.0 / q}
    n = secondary.sum()
    assert abs(out[secondary].mean() - 1.0) < 4.0 * np.sqrt((1.0 - q) / (q * n)) + 1e-12   # unbiased
    assert asked == (~secondary).sum() + (out[secondary] > 0).sum()        # the skipped ones cost nothing


def test_the_gather_coins_are_a_function_of_seed_sample_and_point():
    points = np.random.default_rng(2).random((3, 1000))
    sample = np.arange(1000)
    a = caustics_module.gather_coins(7, sample, points)
    assert np.array_equal(a, caustics_module.gather_coins(7, sample, points.copy()))
    assert not np.array_equal(a, caustics_module.gather_coins(8, sample, points))          # control: the seed
    assert not np.array_equal(a, caustics_module.gather_coins(7, sample + 1, points))
    assert np.all((0.0 <= a) & (a < 1.0)) and abs(a.mean() - 0.5) < 0.05


def test_the_automatic_photon_count_follows_the_pixels():
    """photons_per_pass 0: a quarter of the render's pixels a pass, within 1000 and 50 000; a count
    set is kept."""
    from engine.integrators.photons.caustics import photons_per_pass
    auto = RenderSettings()
    assert auto.photons_per_pass == 0
    assert photons_per_pass(auto, caustic_scene((96, 96))) == 2304
    assert photons_per_pass(auto, caustic_scene((256, 128))) == 8192
    assert photons_per_pass(auto, caustic_scene((16, 16))) == 1000
    assert photons_per_pass(auto, caustic_scene((1920, 1080))) == 50000
    assert photons_per_pass(RenderSettings(photons_per_pass=3000), caustic_scene((96, 96))) == 3000
    assert prepared(caustic_scene((96, 96))).tracer.photons.photons == 2304
