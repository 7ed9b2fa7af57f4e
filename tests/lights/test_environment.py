"""The image world (engine/lights/environment.py): Cycles' projections, the importance sampler
against its own density (χ²), the sampled pdf against the evaluated one, the light-kind protocol,
a white image as a furnace, and scene files.

Controls: the χ² test fails a sampler that forgets the equirectangular map's sin theta (judged by
the density with it); the furnace fails an image of 0.9.  A Mapping matrix with a non-uniform scale
(which has a Jacobian; a rotation has none) passes the χ² test.
"""
import numpy as np
import pytest

from engine.lights.environment import (EnvironmentLight, EnvironmentMap, PiecewiseConstant2D,
                                       direction_to_equirectangular, direction_to_mirror_ball,
                                       equirectangular_to_direction, mirror_ball_to_direction)
from engine.scene.model import Environment
from scripts.make_sample_hdr import sky_pixels
from tests.chi_square import ALPHA, sphere_chi2
from tests.lights.test_protocol import check_kind

N_CHI2 = 4                                      # Sidak correction over the χ² tests below
ALPHA_EACH = 1.0 - (1.0 - ALPHA) ** (1.0 / N_CHI2)


def unit(d):
    return d / np.sqrt((d * d).sum(axis=0))


def random_image(seed=0, h=16, w=32):
    """A lumpy image: smooth variation times a few bright texels."""
    rng = np.random.default_rng(seed)
    px = rng.gamma(0.7, 1.0, (h, w, 3)).astype(np.float32)
    px[3, 5] *= 40.0
    px[12, 20] *= 80.0
    return px


def env_map(pixels, sin_theta=True, **kw):
    return EnvironmentMap(Environment(0, **kw), pixels, False, sin_theta_in_density=sin_theta)


def test_projections_match_cycles_conventions():
    # Cycles: u = 0.5 looks along +x, u = 0.75 along -y, v = 1 straight up; mirror ball centre = -y.
    d = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]).T
    u, v = direction_to_equirectangular(d)
    assert np.allclose(u, [0.5, 0.75, 0.5]) and np.allclose(v, [0.5, 0.5, 1.0])
    u, v = direction_to_mirror_ball(np.array([[0.0], [-1.0], [0.0]]))
    assert np.allclose([u[0], v[0]], [0.5, 0.5])
    rng = np.random.default_rng(1)
    d = unit(rng.normal(size=(3, 1000)))
    back, _ = equirectangular_to_direction(*direction_to_equirectangular(d))
    assert np.allclose(back, d, atol=1e-12)
    d = d[:, d[1] < 0.99]
    back, on = mirror_ball_to_direction(*direction_to_mirror_ball(d))
    assert on.all() and np.allclose(back, d, atol=1e-9)


def test_piecewise_constant_2d_draws_its_density():
    rng = np.random.default_rng(2)
    w = rng.random((6, 9)) * (rng.random((6, 9)) > 0.3)
    dist = PiecewiseConstant2D(w)
    u, v, p = dist.sample(*rng.random((2, 200_000)))
    assert np.array_equal(p, dist.pdf(u, v)) and (p > 0).all()
    counts = np.histogram2d(v, u, bins=(6, 9), range=((0, 1), (0, 1)))[0]
    assert np.allclose(counts / 200_000, w / w.sum(), atol=3e-3)


@pytest.mark.parametrize("projection", ["equirectangular", "mirror_ball"])
def test_sampled_pdf_equals_evaluated_pdf(projection):
    m = env_map(random_image(), projection=projection)
    d, pdf = m.sample(*np.random.default_rng(3).random((2, 50_000)))
    ok = pdf > 0
    assert ok.mean() > 0.7
    assert np.allclose(m.pdf(d[:, ok]), pdf[ok], rtol=1e-9, atol=0)


@pytest.mark.parametrize("projection,matrix", [
    ("equirectangular", ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))),
    ("mirror_ball", ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))),
    ("equirectangular", ((0.6, -0.8, 0.0), (0.4, 0.3, 0.5), (0.0, 0.2, 2.0)))])
def test_image_sampler_chi2(projection, matrix):
    m = env_map(random_image(), projection=projection, matrix=matrix)
    p, dof = sphere_chi2(lambda u: np.where(m.sample(u[0], u[1])[1] > 0, m.sample(u[0], u[1])[0], 0.0), m.pdf,
                         n=100_000, z_bins=16, phi_bins=32, seed=4)
    assert p > ALPHA_EACH, (p, dof)


def test_chi2_control_fails_without_sin_theta():
    """Control: a sampler that leaves out the equirectangular map's sin theta, judged by the
    density the map claims (with it), fails."""
    right, wrong = env_map(random_image()), env_map(random_image(), sin_theta=False)
    p, _ = sphere_chi2(lambda u: wrong.sample(u[0], u[1])[0], right.pdf, n=100_000, z_bins=16, phi_bins=32, seed=4)
    assert p < 1e-6, p


def test_environment_light_follows_the_protocol():
    m = env_map(random_image(5))
    light = EnvironmentLight(m, 3.0)
    assert check_kind(light) > 10_000
    rotated = env_map(random_image(5), matrix=((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
    assert check_kind(EnvironmentLight(rotated, 3.0)) > 10_000


def test_sun_texel_is_seen_where_cycles_puts_it():
    """The sample sky's sun texels: radiance along the sun direction, sky elsewhere."""
    from scripts.make_sample_hdr import SUN_DIRECTION, SUN_RADIANCE
    m = env_map(sky_pixels(), interpolation="Closest")
    sun = unit(np.array(SUN_DIRECTION, dtype=np.float64)[:, None])
    assert np.allclose(m.radiance(sun)[:, 0], SUN_RADIANCE)
    assert m.radiance(-sun)[:, 0].max() < 1.0


def furnace(pixels_value, estimator):
    from engine.api import render
    from engine.core.settings import RenderSettings
    from engine.scene.model import Camera, Material, Scene, Sphere
    from engine.scene.textures import ImageTexture
    px = np.full((8, 16, 3), pixels_value, np.float32)
    scene = Scene(Camera.look_at((0, -3.0, 0), (0, 0, 0)), [Material("White", color=(1, 1, 1))],
                  spheres=[Sphere("Ball", (0, 0, 0), 1.0, 0)], resolution=(8, 8),
                  textures=[ImageTexture("white", pixels=px, colorspace="Linear", is_float=True)],
                  environment=Environment(0))
    settings = RenderSettings(samples=64, max_depth=48, threads=1, estimator=estimator, russian_roulette=False)
    return render(scene, settings, log=lambda *a: None).image


@pytest.mark.parametrize("estimator", ["mis", "report"])
def test_white_environment_is_a_furnace(estimator):
    """An albedo-1 diffuse sphere under a white image renders 1 everywhere (MIS: within noise)."""
    image = furnace(1.0, estimator)
    assert abs(image.mean() - 1.0) < 3e-3 and np.abs(image - 1.0).max() < 0.12


def test_furnace_control_fails_a_dimmer_image():
    assert abs(furnace(0.9, "mis").mean() - 1.0) > 0.05


def test_scene_file_keeps_the_environment(tmp_path):
    from engine.scene.builtin import cornell_scene
    from engine.scene.files import load_scene, save_scene
    from engine.scene.textures import ImageTexture
    scene = cornell_scene(resolution=(8, 8))
    scene.textures.append(ImageTexture("sky", pixels=sky_pixels(16, 8), colorspace="Linear", is_float=True))
    scene.environment = Environment(len(scene.textures) - 1, strength=2.0, projection="mirror_ball",
                                    matrix=((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
                                    camera_color=(0.1, 0.2, 0.3), name="Sky")
    save_scene(scene, str(tmp_path / "s.json"))
    again = load_scene(str(tmp_path / "s.json"))
    assert again.environment == scene.environment
    again.validate()
    again.environment.projection = "cube"
    with pytest.raises(Exception, match="World 'Sky'"):
        again.validate()


def test_camera_rays_see_their_own_background():
    """Light Path "Is Camera Ray": camera rays that miss see camera_color; the ball is lit by the image."""
    from engine.api import render
    from engine.core.settings import RenderSettings
    from engine.scene.model import Camera, Material, Scene, Sphere
    from engine.scene.textures import ImageTexture
    px = np.full((8, 16, 3), 1.0, np.float32)
    scene = Scene(Camera.look_at((0, -3.0, 0), (0, 0, 0)), [Material("White", color=(1, 1, 1))],
                  spheres=[Sphere("Ball", (0, 0, 0), 0.5, 0)], resolution=(8, 8),
                  textures=[ImageTexture("white", pixels=px, colorspace="Linear", is_float=True)],
                  environment=Environment(0, strength=0.5, camera_color=(0.1, 0.2, 0.3)))
    image = render(scene, RenderSettings(samples=16, threads=1), log=lambda *a: None).image
    assert np.allclose(image[0, 0], (0.1, 0.2, 0.3)) and np.allclose(image[4, 4], 0.5, atol=0.05)


def test_sample_sky_file_reads_back(tmp_path):
    """scripts/make_sample_hdr.py's file (top row first) is read back bottom row first, as the map wants."""
    from engine.lights.environment import load_pixels
    from engine.scene.textures import ImageTexture
    from scripts.make_sample_hdr import write
    write(str(tmp_path / "sky.exr"))
    pixels, decode_after = load_pixels(ImageTexture("sky", path=str(tmp_path / "sky.exr"), colorspace="Linear"))
    assert not decode_after and np.array_equal(pixels[..., :3], sky_pixels())
    bytes_ = np.clip(np.rint(sky_pixels() * 255), 0, 255).astype(np.uint8)       # an 8-bit sRGB image
    pixels, decode_after = load_pixels(ImageTexture("sky8", pixels=bytes_, colorspace="sRGB"))
    m = EnvironmentMap(Environment(0, interpolation="Closest"), pixels, decode_after)
    d = unit(np.array([[0.3], [0.2], [0.9]]))
    from engine.materials.textures import srgb_to_linear
    u, v = direction_to_equirectangular(d)
    texel = bytes_[int(v[0] * 64), int(u[0] * 128)] / 255.0
    assert np.allclose(m.radiance(d)[:, 0], srgb_to_linear(texel), rtol=1e-6)


def luminance_spread(monkeypatch, map_width):
    """The light samples' luminance / pdf on the sample sky (a small, very bright sun): its
    coefficient of variation (0 for a density exactly proportional to the luminance)."""
    from engine.lights import environment
    from engine.materials.mix import LUMINANCE
    monkeypatch.setattr(environment, "MAP_WIDTH", map_width)
    m = env_map(sky_pixels())
    rng = np.random.default_rng(3)
    d, pdf = m.sample(rng.random(20000), rng.random(20000))
    f = (m.radiance(d).T @ LUMINANCE) / pdf
    return f.std() / f.mean()


def test_density_follows_the_bilinear_sun_as_cycles_map(monkeypatch):
    # The 128 x 64 sky on a 1024 x 512 map (Cycles' default Map Resolution): radiance / pdf nearly
    # constant (0.06 here); the control, one cell per texel, spreads the sun's bilinear edge (0.44).
    assert luminance_spread(monkeypatch, 1024) < 0.15
    assert luminance_spread(monkeypatch, 0) > 0.3
