"""The film settings in a render (engine/rendering/frame.py FrameFilm.display, engine/film/accumulator.py,
engine/integrators/path_tracer.py misses): exposure scales the image, a transparent film gives alpha 0
where the camera sees only the background and 1 where it sees only surfaces, and composited over the
background it is the opaque render; the pixel filter moves the camera samples; the animated seed
(engine/core/settings.py animated_seed) is a new seed each frame."""
import dataclasses

import numpy as np

from engine.api import render
from engine.core.settings import RenderSettings, animated_seed
from engine.scene.model import Camera
from tests.scenes import camera_inside_sphere_scene, object_in_uniform_background

BASE = RenderSettings(samples=8, threads=1, parallelism="threads", seed=3)


def run(scene, **changes):
    return render(scene, dataclasses.replace(BASE, **changes), log=lambda *a: None)


def test_exposure_scales_the_image_exactly():
    scene = object_in_uniform_background("diffuse", color=0.5, resolution=(12, 12))
    base, bright = run(scene), run(scene, film_exposure=2.0)
    assert base.image.mean() > 0.1
    assert np.array_equal(bright.image, base.image * 2)                   # x2 is exact in binary
    assert np.allclose(bright.variance, base.variance * 4, rtol=1e-6)
    assert bright.alpha is None and bright.combined().shape[-1] == 3


def test_transparent_film_alpha():
    scene = object_in_uniform_background("diffuse", color=0.5, resolution=(16, 16))
    opaque, clear = run(scene), run(scene, film_transparent=True)
    alpha = clear.alpha
    assert clear.combined().shape == (16, 16, 4)
    assert alpha.min() == 0.0 and alpha.max() == 1.0 and 0.2 < alpha.mean() < 0.8   # the ball and around it
    assert np.all(clear.image[alpha == 0.0] == 0.0)                       # premultiplied: no world seen
    # over the background (radiance 1) it is the opaque render: the same samples, the misses aside
    assert np.allclose(clear.image + (1.0 - alpha)[..., None] * 1.0, opaque.image, atol=1e-5)
    # the world still lights the ball
    assert clear.image[alpha == 1.0].mean() > 0.2


def test_transparent_film_all_background_and_all_covered():
    sky = object_in_uniform_background("diffuse", resolution=(8, 8))
    sky.camera = Camera.look_at((0, -3, 0), (0, -6, 0), lens=50.0)        # looking away from the ball
    away = run(sky, film_transparent=True)
    assert np.all(away.alpha == 0.0) and np.all(away.image == 0.0)
    inside = camera_inside_sphere_scene()
    covered, opaque = run(inside, film_transparent=True), run(inside)
    assert np.all(covered.alpha == 1.0)
    assert np.array_equal(covered.image, opaque.image)


def test_pixel_filter_moves_the_samples():
    scene = object_in_uniform_background("diffuse", color=0.5, resolution=(12, 12))
    box = run(scene)
    assert np.array_equal(run(scene, pixel_filter="box", filter_width=1.0).image, box.image)
    wide = run(scene, pixel_filter="blackman-harris", filter_width=1.5)
    assert not np.array_equal(wide.image, box.image)
    assert abs(wide.image.mean() - box.image.mean()) < 0.05               # the same picture, softer edges


def test_animated_seed():
    seeds = [animated_seed(0, frame) for frame in range(1, 6)]
    assert len(set(seeds)) == 5 and all(0 <= s < 2**31 for s in seeds)
    assert animated_seed(0, 1) == animated_seed(0, 1) != animated_seed(1, 1)


def test_transparent_images_are_premultiplied_exr_and_straight_png(tmp_path):
    """engine/film/image_files.py: the EXR keeps premultiplied RGBA; the PNG stores straight alpha
    (the colour divided by alpha, then sRGB), as Blender saves PNGs."""
    import OpenImageIO as oiio
    from engine.film.image_files import linear_to_srgb, read_image, write_exr, write_png
    rgba = np.zeros((2, 2, 4), np.float32)
    rgba[0, 0] = (0.25, 0.1, 0.0, 0.5)              # half covered
    rgba[0, 1] = (0.5, 0.5, 0.5, 1.0)
    write_exr(str(tmp_path / "a.exr"), rgba)
    assert np.array_equal(read_image(str(tmp_path / "a.exr")), rgba)
    write_png(str(tmp_path / "a.png"), rgba)
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)     # the stored values (OIIO would premultiply them)
    inp = oiio.ImageInput.open(str(tmp_path / "a.png"), config)
    png = inp.read_image("uint8")
    inp.close()
    assert png.shape == (2, 2, 4)
    expected = np.round(linear_to_srgb(np.array([0.5, 0.2, 0.0])) * 255).astype(int)
    assert np.abs(png[0, 0, :3].astype(int) - expected).max() <= 1 and png[0, 0, 3] in (127, 128)
    assert tuple(png[1, 1]) == (0, 0, 0, 0)
