"""Hard cases S3, S7-S9 and T2, T4-T6 of docs/hard-cases.md."""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.scene.builtin import cornell_scene
from engine.scene.model import DIFFUSE, GLASS, MIRROR, Camera, Material, Quad, Scene, Sphere
from engine.core.errors import SceneError

SILENT = dict(log=lambda *a: None)


def test_s3_mirror_at_grazing_incidence_reflects_the_background_exactly():
    """Camera 0.05 units above a huge mirror, looking almost along it: every pixel == 1."""
    mats = [Material("Mirror", MIRROR, (1, 1, 1))]
    big = 1e4
    floor = Quad("Mirror", np.array([(-big, -big, 0), (big, -big, 0), (big, big, 0), (-big, big, 0)], float), 0)
    cam = Camera.look_at((0, 0, 0.05), (0, 1000, 0.05 - 1000 * np.tan(np.radians(0.01))), lens=200)
    scene = Scene(cam, mats, quads=[floor], background=(1, 1, 1), resolution=(16, 16))
    img = render(scene, RenderSettings(samples=4), **SILENT).image
    assert np.abs(img - 1).max() < 1e-6


@pytest.mark.parametrize("fresnel", ["schlick", "exact"])
def test_s7_camera_inside_a_glass_sphere_sees_the_background(fresnel):
    """Cycles' convention (no 1/eta^2): every pixel == 1 in a uniform environment."""
    mats = [Material("Glass", GLASS, (1, 1, 1), ior=1.5)]
    scene = Scene(Camera.look_at((0.1, 0.2, 0.0), (1, 3, 0.5)), mats,
                  spheres=[Sphere("Bubble", (0, 0, 0), 1.0, 0)], background=(1, 1, 1), resolution=(12, 12))
    result = render(scene, RenderSettings(samples=8, max_depth=128, fresnel=fresnel), **SILENT)
    assert np.abs(result.image - 1).max() < 1e-6
    assert result.stats["nonfinite_samples"] == 0


def test_s8_zero_area_light_is_rejected_with_its_name():
    mats = [Material("Lamp", color=(0, 0, 0), emission=(5, 5, 5))]
    flat = np.array([(0, 0, 1), (1, 0, 1), (2, 0, 1), (3, 0, 1)], float)
    scene = Scene(Camera.look_at((0, -5, 0), (0, 0, 0)), mats, quads=[Quad("Lamp", flat, 0)])
    with pytest.raises(SceneError, match="Object 'Lamp'"):
        render(scene, RenderSettings(samples=1), **SILENT)


def test_s8_points_in_the_light_plane_and_on_the_light_get_no_nan():
    """A floor coplanar with the light (cos_l = 0) and a lamp that is itself diffuse, so its
    own points sample it at r -> 0 and cos = 0: contributions exactly 0, never NaN."""
    mats = [Material("Floor", DIFFUSE, (0.8, 0.8, 0.8)),
            Material("Lamp", DIFFUSE, (0.5, 0.5, 0.5), emission=(3, 3, 3))]
    floor = Quad("Floor", np.array([(-5, 1, 0), (5, 1, 0), (5, 5, 0), (-5, 5, 0)], float), 0)
    lamp = Quad("Lamp", np.array([(-1, -1, 0), (-1, 1, 0), (1, 1, 0), (1, -1, 0)], float), 1)
    wall = Quad("Wall", np.array([(-5, 3, 0), (5, 3, 0), (5, 3, 4), (-5, 3, 4)], float), 0)
    scene = Scene(Camera.look_at((0, -6, 4), (0, 0, 0)), mats, quads=[lamp, floor, wall], resolution=(24, 24))
    result = render(scene, RenderSettings(samples=8, max_depth=0), **SILENT)
    assert result.stats["nonfinite_samples"] == 0
    assert np.isfinite(result.image).all()
    # With direct light only, a point on the lamp sees nothing but its own coplanar lamp: exactly Le.
    assert np.allclose(result.image[12, 12], 3.0, atol=1e-6)
    assert result.image.max() <= 3.0 + 1e-6


@pytest.mark.parametrize("estimator", ["report", "mis"])
def test_s9_near_field_light_estimates_stay_finite(estimator):
    """1x1 light 1e-3 above the receiver: area-sampling weights ~ h^2 / r^4 are heavy-tailed.

    Numerical stability is asserted for both estimators (no inf, no NaN).  Under `report` the
    estimate documents the known weakness of uniform area sampling (pdf 1/A, eq. 2.11) that the
    report's §4 points out: most pixel means fall far below F = 0.99999673 and a few are far
    above.  Sampling the light by solid angle (`mis`) removes it: every pixel is close to F.
    """
    from tests.scenes import floor_under_square_light, form_factor_square
    scene = floor_under_square_light(albedo=1.0, height=1e-3)
    scene.camera = Camera.look_at((0, 0, 0.5e-3), (0, 0, 0), up=(0, 1, 0), lens=2e5)
    result = render(scene, RenderSettings(samples=2048, max_depth=0, shadow_rays=4, estimator=estimator), **SILENT)
    assert result.stats["nonfinite_samples"] == 0 and np.isfinite(result.image).all()
    assert np.isfinite(result.variance).all()
    truth = form_factor_square(1.0, 1e-3)
    values = result.image[..., 0]
    if estimator == "report":
        assert np.median(values) < 0.5 * truth < truth < values.max()   # the documented heavy tail
    else:
        assert np.abs(values - truth).max() < 0.02 * truth
        assert abs(values.mean() - truth) < 3 * np.sqrt(result.variance[..., 0].sum()) / values.size + 1e-6


def test_t2_pbrt_furnace_small_emitter_inside_a_diffuse_sphere():
    """Inward sphere Kd 0.5 around a small emissive sphere: L on the wall = Le_wall-equivalent.

    With emitted power P = Le * 4 pi r^2 * pi from the small sphere, the irradiance on the
    wall of radius R is E = P / (4 pi R^2) from direct light; the multiple bounces inside the
    closed sphere multiply the radiosity by 1/(1 - rho): L = rho E / (pi (1 - rho)).
    """
    rho, le, r, big = 0.5, 1.0, 0.05, 1.0
    mats = [Material("Wall", DIFFUSE, (rho,) * 3), Material("Bulb", DIFFUSE, (0, 0, 0), emission=(le,) * 3)]
    scene = Scene(Camera.look_at((0, 0, -0.5), (0, 0.3, -1), lens=35), mats,
                  spheres=[Sphere("Wall", (0, 0, 0), big, 0), Sphere("Bulb", (0, 0, 0), r, 1)], resolution=(8, 8))
    result = render(scene, RenderSettings(samples=512, max_depth=64, shadow_rays=2), **SILENT)
    e = le * np.pi * 4 * np.pi * r ** 2 / (4 * np.pi * big ** 2)
    # The bulb also blocks a little of the inter-reflected light: about (r/R)^2 / 4 of the wall's view.
    expected = rho * e / (np.pi * (1 - rho))
    mean = result.image[..., 0].mean()
    se = np.sqrt(result.variance[..., 0].sum()) / result.image[..., 0].size
    assert abs(mean - expected) < 3 * se + 0.002 * expected, (mean, expected, se)


def test_t4_black_materials_and_zero_throughput_never_divide_by_zero():
    scene = cornell_scene((24, 24))
    for m in scene.materials:
        if not m.is_emissive:
            m.color = (0.0, 0.0, 0.0)
    result = render(scene, RenderSettings(samples=4, rr_start_depth=0), **SILENT)
    assert result.stats["nonfinite_samples"] == 0 and np.isfinite(result.image).all()
    assert result.stats["rays"]["extension"] < result.stats["rays"]["camera"]  # black paths end


def test_t5_built_in_scene_has_no_nonfinite_sample():
    result = render(cornell_scene((48, 48)), RenderSettings(samples=16, fresnel="exact"), **SILENT)
    assert result.stats["nonfinite_samples"] == 0 and np.isfinite(result.image).all()


def test_t6_box_filter_pixel_value_is_the_covered_fraction():
    """An emitter edge crossing pixels at a known position: pixel value = covered fraction."""
    mats = [Material("Lamp", color=(0, 0, 0), emission=(1, 1, 1))]
    # Orthographic-like view of a plane at distance 10 with lens chosen so 1 px = 0.01 units.
    w = 20
    lens = 36.0 * 10 / (w * 0.01)
    edge = 0.003                                           # 0.3 px into pixel column 10
    lamp = Quad("Lamp", np.array([(edge, -5, 0), (edge, 5, 0), (-5, 5, 0), (-5, -5, 0)], float)[::-1], 0)
    scene = Scene(Camera.look_at((0, 0, 10), (0, 0, 0), up=(0, 1, 0), lens=lens), mats, quads=[lamp],
                  resolution=(w, 4))
    result = render(scene, RenderSettings(samples=4096, max_depth=0), **SILENT)
    row = result.image[:, :, 0].mean(axis=0)
    assert np.allclose(row[:10], 1.0) and np.allclose(row[11:], 0.0)
    se = np.sqrt(result.variance[:, 10, 0].mean() / 4)
    assert abs(row[10] - 0.3) < 3 * se + 1e-3, (row[10], se)


@pytest.mark.parametrize("estimator", ["report", "solid-angle"])
def test_t1_every_shadow_ray_inside_an_emitting_sphere_weighs_exactly_rho_le(estimator):
    """Two points on a sphere's inside: cos cos / r^2 = 1/(4 R^2), so V G / p(y) = pi and each
    next-event sample is exactly rho * Le.  A self-occluded shadow ray would give 0."""
    from engine.geometry.scene_geometry import Counters
    from engine.rendering.session import PreparedScene as Renderer
    from engine.geometry.shapes.spheres import surface_point
    from engine.materials.protocol import ShadingPoint
    rho, le, radius = 0.7, 2.0, 3.0
    mats = [Material("Shell", DIFFUSE, (rho,) * 3, emission=(le,) * 3)]
    scene = Scene(Camera.look_at((0, 0, 0), (0, 1, 0)), mats, spheres=[Sphere("Shell", (1e3, 2e3, -5e2), radius, 0)])
    tracer = Renderer(scene, RenderSettings(shadow_rays=1, estimator=estimator), **SILENT).tracer
    rng = np.random.default_rng(21)
    n = 20000
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    centre = np.array(scene.spheres[0].center)
    o = np.tile(centre, (n, 1))
    t = np.full(n, radius)
    point, normal, offset = surface_point(o.T, dirs.T, t, np.tile(centre, (n, 1)).T, np.full(n, radius))
    inward = -normal                                      # the shell's inside faces its centre
    hit = ShadingPoint(inward, inward, inward, normal, np.full((3, n), rho), np.zeros(n, dtype=np.int64))
    direct = tracer.direct_light(tracer.bsdfs[0], hit, point, offset, rng, Counters())
    assert direct.shape == (3, n)
    # Samples landing (almost) on the shading point itself carry cos -> 0 and are dropped: none here.
    assert np.allclose(direct, rho * le / np.pi * np.pi, rtol=1e-6)


def test_s8_back_facing_area_light_gives_exactly_zero():
    from engine.scene.model import AreaLight
    mats = [Material("Floor", DIFFUSE, (0.8, 0.8, 0.8))]
    floor = Quad("Floor", np.array([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], float), 0)
    facing_up = np.array([(-0.5, -0.5, 1), (0.5, -0.5, 1), (0.5, 0.5, 1), (-0.5, 0.5, 1)], float)
    scene = Scene(Camera.look_at((0, -3, 2), (0, 0, 0)), mats, quads=[floor], resolution=(12, 12),
                  lights=[AreaLight("Lamp", facing_up, (5.0, 5.0, 5.0))])
    result = render(scene, RenderSettings(samples=16, max_depth=3), **SILENT)
    assert result.image.max() == 0.0 and result.stats["nonfinite_samples"] == 0


def _glass_ball_on_floor(lift=0.0):
    mats = [Material("Floor", DIFFUSE, (0.8, 0.8, 0.8)), Material("Glass", GLASS, (1, 1, 1), ior=1.5),
            Material("Lamp", DIFFUSE, (0, 0, 0), emission=(4, 4, 4))]
    floor = Quad("Floor", np.array([(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], float), 0)
    lamp = Quad("Lamp", np.array([(-1, -1, 3), (-1, 1, 3), (1, 1, 3), (1, -1, 3)], float), 2)
    ball = Sphere("Ball", (0, 0, 0.5 + lift), 0.5, 1)
    # Close-up of the contact point, from the side and slightly above.
    cam = Camera.look_at((0, -1.6, 0.35), (0, 0, 0.05), lens=60)
    return Scene(cam, mats, quads=[floor, lamp], spheres=[ball], background=(0.3, 0.3, 0.3), resolution=(24, 24))


def _uv_sphere_mesh(center, radius, n_u, n_v, material):
    theta = np.linspace(0, np.pi, n_v + 1)
    phi = np.linspace(0, 2 * np.pi, n_u, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    v = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3) * radius + center
    i, j = np.meshgrid(np.arange(n_v), np.arange(n_u), indexing="ij")
    a, b = i * n_u + j, i * n_u + (j + 1) % n_u
    c, d = (i + 1) * n_u + (j + 1) % n_u, (i + 1) * n_u + j
    f = np.concatenate([np.stack([a.ravel(), d.ravel(), c.ravel()], 1), np.stack([a.ravel(), c.ravel(), b.ravel()], 1)])
    from engine.scene.model import TriangleMesh
    return TriangleMesh("Ball (mesh)", v, f, np.full(len(f), material))


def test_glass_resting_on_a_floor_has_no_black_ring_and_no_leak():
    """A glass ball touching a floor at one point, seen through the glass near the contact.

    Oracle: the same ball as a 262k-triangle mesh, traced by Embree with its own offsets.  The
    implicit-sphere path must agree block by block (a distance epsilon of 2 cm in the sphere
    test, which leaks light under the contact, fails this at z = 6; faceting gives up to z = 3.5).
    """
    settings = RenderSettings(samples=512, max_depth=12, fresnel="exact", seed=3)
    implicit = render(_glass_ball_on_floor(0.0), settings, **SILENT)
    scene = _glass_ball_on_floor(0.0)
    ball = scene.spheres.pop()
    scene.meshes.append(_uv_sphere_mesh(np.array(ball.center), ball.radius, 512, 256, ball.material_id))
    mesh = render(scene, settings, **SILENT)
    assert implicit.stats["nonfinite_samples"] == 0 and mesh.stats["nonfinite_samples"] == 0
    a, b = implicit.image[..., 1], mesh.image[..., 1]
    va, vb = implicit.variance[..., 1], mesh.variance[..., 1]
    for y in range(8, 24, 4):                              # 4x4 blocks around the contact point
        for x in range(4, 20, 4):
            da, db = a[y:y + 4, x:x + 4].mean(), b[y:y + 4, x:x + 4].mean()
            se = np.sqrt(va[y:y + 4, x:x + 4].sum() + vb[y:y + 4, x:x + 4].sum()) / 16
            assert abs(da - db) < 4.5 * se, (y, x, da, db, se)
    assert (a > 0).all()                                   # no black pixels anywhere
