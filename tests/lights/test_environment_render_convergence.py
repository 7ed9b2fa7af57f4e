"""The image sampler in the path tracer: relMSE of a render under the sample sky
(scripts/make_sample_hdr.py) with the environment light importance-sampled by the image
(engine/lights/environment.py) against the same light sampled by cosine directions about the
normal (as the constant world is, engine/lights/distant.py), both MIS-weighted with the BSDF
samples, at equal samples per pixel, against a long render of the image sampler.  Printed with -s;
the figures are in docs/world.md.  Slow (a few seconds of rendering)."""
import numpy as np
import pytest

from engine.api import render
from engine.core.settings import RenderSettings
from engine.lights import environment as environment_module
from engine.lights.protocol import infinite_sample
from engine.sampling.warps import cosine_directions
from engine.scene.model import Camera, Environment, Material, Quad, Scene, Sphere
from engine.scene.textures import ImageTexture
from scripts.make_sample_hdr import sky_pixels

pytestmark = pytest.mark.slow
RES, SPP, SEEDS = (32, 32), 16, 4


def sky_scene():
    floor = [(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)]
    return Scene(Camera.look_at((0.0, -3.6, 1.4), (0.0, 0.3, 0.5), lens=35.0),
                 [Material("White", color=(0.7, 0.7, 0.7)), Material("Orange", color=(0.8, 0.45, 0.2))],
                 spheres=[Sphere("Ball", (-0.35, 0.2, 0.45), 0.45, 1)], quads=[Quad("Floor", floor, 0)],
                 resolution=RES, textures=[ImageTexture("sky", pixels=sky_pixels(), colorspace="Linear", is_float=True)],
                 environment=Environment(0))


class CosineEnvironmentLight(environment_module.EnvironmentLight):
    """The same light, sampled as the constant world is: cosine directions about the normal."""

    def sample_li(self, x, idx, u1, u2, n=None, solid_angle=True):
        d = cosine_directions(u1, u2, n)
        return infinite_sample(x, d, self.map.radiance(d), self.pdf_li(x, idx, None, n, d))

    def pdf_li(self, x, idx, point, n=None, direction=None, solid_angle=True, pmf=1.0):
        return pmf * np.maximum((direction * n).sum(axis=0), 0.0) / np.pi


def renders(spp, seeds):
    return np.stack([render(sky_scene(), RenderSettings(samples=spp, seed=s, threads=1), log=lambda *a: None).image
                     for s in seeds]).astype(np.float64)


def rel_mse(images, reference):
    return float(np.mean((images - reference) ** 2 / (reference ** 2 + 1e-2)))


def test_image_sampling_converges_faster_than_cosine_in_the_path_tracer(monkeypatch):
    reference = renders(512, [99]).mean(axis=0)
    image = rel_mse(renders(SPP, range(SEEDS)), reference)
    monkeypatch.setattr("engine.lights.emitters.EnvironmentLight", CosineEnvironmentLight)
    cosine = rel_mse(renders(SPP, range(SEEDS)), reference)
    print(f"\nrender relMSE at {SPP} spp: image sampling {image:.4g}, cosine sampling {cosine:.4g} "
          f"(ratio {cosine / image:.1f})")
    assert cosine / image >= 10.0
