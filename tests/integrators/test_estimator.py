"""The report's estimator against analytic answers (docs/hard-cases.md T1, S10, T3, S7, T4)."""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.scene.model import DIFFUSE, GLASS, MIRROR

from tests.scenes import (camera_inside_sphere_scene, diffuse_box_scene, floor_under_square_light,
                     form_factor_square, object_in_uniform_background)

Z = 3.0


def quiet(**kw):
    return RenderSettings(**{"threads": 2, "tile_size": 16, **kw})


def image_mean_and_se(result):
    """Mean of all pixel values of channel 0 and its standard error from per-pixel variances."""
    img, var = result.image[..., 0], result.variance[..., 0]
    n = img.size
    return img.mean(), np.sqrt(var.sum()) / n


def test_white_furnace_closed_emitting_sphere():
    """L = Le / (1 - rho): rho 0.8, Le 1 -> 5 (double-counted emission would give 9)."""
    scene = camera_inside_sphere_scene(albedo=0.8, emission=1.0)
    result = render(scene, quiet(samples=256, max_depth=400), log=lambda *a: None)
    mean, se = image_mean_and_se(result)
    assert se < 0.05
    assert abs(mean - 5.0) < Z * se, (mean, se)
    assert result.stats["nonfinite_samples"] == 0


def test_furnace_without_shadow_rays_converges_to_the_same_value():
    """With 0 shadow rays emission is found by BSDF sampling alone: still 5."""
    scene = camera_inside_sphere_scene(albedo=0.8, emission=1.0)
    result = render(scene, quiet(samples=256, max_depth=400, shadow_rays=0), log=lambda *a: None)
    mean, se = image_mean_and_se(result)
    assert abs(mean - 5.0) < Z * se, (mean, se)


@pytest.mark.parametrize("shadow_rays", [1, 4])
def test_diffuse_point_under_square_light_matches_form_factor(shadow_rays):
    """Direct light only (max depth 0): L = rho * Le * F, F = 0.23945647 for 1x1 at height 1."""
    rho = 0.8
    scene = floor_under_square_light(albedo=rho)
    result = render(scene, quiet(samples=4096, max_depth=0, shadow_rays=shadow_rays), log=lambda *a: None)
    expected = rho * form_factor_square(1.0, 1.0)
    assert form_factor_square(1.0, 1.0) == pytest.approx(0.23945647, abs=1e-8)
    mean, se = image_mean_and_se(result)
    assert abs(mean - expected) < Z * se, (mean, expected, se)
    assert se < 0.01 * expected


def test_form_factor_test_fails_with_a_wrong_light_strength():
    """Control: the same check rejects a light 5 % too bright."""
    scene = floor_under_square_light(albedo=0.8, radiance=1.05)
    result = render(scene, quiet(samples=4096, max_depth=0), log=lambda *a: None)
    mean, se = image_mean_and_se(result)
    assert abs(mean - 0.8 * form_factor_square(1.0, 1.0)) > Z * se


def test_mirror_sphere_in_uniform_background_is_invisible():
    result = render(object_in_uniform_background(MIRROR), quiet(samples=4), log=lambda *a: None)
    assert np.abs(result.image - 1.0).max() < 1e-6


@pytest.mark.parametrize("fresnel", ["schlick", "exact"])
def test_glass_sphere_in_uniform_background_is_invisible(fresnel):
    result = render(object_in_uniform_background(GLASS), quiet(samples=8, max_depth=64, fresnel=fresnel),
                    log=lambda *a: None)
    assert np.abs(result.image - 1.0).max() < 1e-6


def test_convex_diffuse_sphere_in_uniform_background_shows_its_albedo():
    """Every sample is exactly rho unless a bounce re-hits the sphere (self-intersection)."""
    result = render(object_in_uniform_background(DIFFUSE, color=0.6), quiet(samples=8), log=lambda *a: None)
    img = result.image[..., 0]
    # Silhouette pixels mix 0.6 and the background 1; nothing may fall below 0.6.
    assert img.min() > 0.6 - 1e-6
    assert (np.abs(img - 0.6) < 1e-6).sum() > 100


def test_russian_roulette_is_unbiased():
    scene = diffuse_box_scene()
    on = render(scene, quiet(samples=256, max_depth=12, russian_roulette=True, rr_start_depth=1, seed=1),
                log=lambda *a: None)
    off = render(scene, quiet(samples=256, max_depth=12, russian_roulette=False, seed=2), log=lambda *a: None)
    m_on, se_on = image_mean_and_se(on)
    m_off, se_off = image_mean_and_se(off)
    assert abs(m_on - m_off) < Z * np.hypot(se_on, se_off), (m_on, m_off, se_on, se_off)
    # Roulette must actually shorten paths.
    assert on.stats["rays"]["extension"] < 0.8 * off.stats["rays"]["extension"]


def test_image_is_identical_across_thread_counts():
    scene = diffuse_box_scene()
    one = render(scene, RenderSettings(samples=8, threads=1, tile_size=8, seed=7), log=lambda *a: None)
    two = render(scene, RenderSettings(samples=8, threads=2, tile_size=8, seed=7), log=lambda *a: None)
    assert np.array_equal(one.image, two.image)
    other_seed = render(scene, RenderSettings(samples=8, threads=2, tile_size=8, seed=8), log=lambda *a: None)
    assert not np.array_equal(one.image, other_seed.image)


def _floor_under_area_light(facing_down=True, two_sided=False):
    from engine.scene.model import AreaLight
    scene = floor_under_square_light(albedo=0.8)
    light_quad = scene.quads.pop()          # replace the emissive quad by a light-only AreaLight
    corners = light_quad.corners if facing_down else light_quad.corners[::-1]
    scene.lights.append(AreaLight("Area", corners, (1.0, 1.0, 1.0), two_sided=two_sided))
    return scene


def test_one_sided_area_light_matches_form_factor_and_is_dark_behind():
    """A Blender Area light: lights the side its normal faces (eq. 2.11 with pdf 1/A)."""
    expected = 0.8 * form_factor_square(1.0, 1.0)
    # The quad's corners wind so that its normal points down (-z), towards the floor.
    down = render(_floor_under_area_light(True), quiet(samples=4096, max_depth=0), log=lambda *a: None)
    mean, se = image_mean_and_se(down)
    assert abs(mean - expected) < Z * se, (mean, expected, se)
    up = render(_floor_under_area_light(False), quiet(samples=64, max_depth=0), log=lambda *a: None)
    assert up.image.max() == 0.0
    both = render(_floor_under_area_light(False, two_sided=True), quiet(samples=4096, max_depth=0),
                  log=lambda *a: None)
    mean, se = image_mean_and_se(both)
    assert abs(mean - expected) < Z * se


def test_area_light_is_invisible_to_camera_and_casts_no_shadow():
    from engine.scene.model import Camera
    scene = _floor_under_area_light(True)
    # Camera above the light looking down through it at the floor.
    scene.camera = Camera.look_at((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), lens=20000.0)
    through = render(scene, quiet(samples=1024, max_depth=0), log=lambda *a: None)
    mean, se = image_mean_and_se(through)
    assert abs(mean - 0.8 * form_factor_square(1.0, 1.0)) < Z * se
