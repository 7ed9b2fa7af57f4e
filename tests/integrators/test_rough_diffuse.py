"""Rough diffuse materials through the whole tracer (Material.diffuse_roughness, the ROUGH_DIFFUSE
row of engine/materials/table.py, the model of Scene.cycles_version):

* roughness 0 renders bit for bit as Lambert (the Lambertian group, no rough-diffuse effect);
* a white sphere of roughness 1 under a uniform white sky (convex: one bounce, a pixel reads the
  lobe's albedo at its angle): 1 in 4.3+ mode; in 3.x mode the closed form E(mu) of the FON lobe
  (docs/materials.md: E(1) = 0.7765, E_avg = 0.8328 at roughness 1), the control being each
  mode against the other's figure.
"""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.materials.oren_nayar import fon_albedo, fon_coefficients
from engine.scene.model import DIFFUSE, Camera, Material, Quad, Scene, Sphere

SILENT = dict(log=lambda *a: None)


def settings(**kw):
    return RenderSettings(**{"threads": 2, "tile_size": 16, **kw})


def room(diffuse_roughness=None):
    """A closed box of diffuse walls lit by an emissive ceiling patch."""
    extra = {} if diffuse_roughness is None else {"diffuse_roughness": diffuse_roughness}
    mats = [Material("Wall", DIFFUSE, (0.7, 0.6, 0.5), **extra),
            Material("Lamp", DIFFUSE, (0, 0, 0), emission=(5.0, 5.0, 5.0))]
    c = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]   # inwards
    quads = [Quad(f"Wall {i}", c[list(f)], 0) for i, f in enumerate(faces)]
    quads.append(Quad("Lamp", np.array([[0.4, 0.4, 0.99], [0.4, 0.6, 0.99], [0.6, 0.6, 0.99], [0.6, 0.4, 0.99]]), 1))
    camera = Camera.look_at((0.5, 0.05, 0.5), (0.5, 1.0, 0.45), up=(0, 0, 1), lens=18.0)
    return Scene(camera, mats, quads=quads, resolution=(24, 24))


def test_roughness_zero_renders_bit_for_bit_as_lambert():
    lambert = render(room(), settings(samples=16, seed=3), **SILENT)
    zero = render(room(0.0), settings(samples=16, seed=3), **SILENT)
    assert not zero.stats["effects"]["rough_diffuse"]
    assert np.array_equal(lambert.image, zero.image) and np.array_equal(lambert.variance, zero.variance)


def test_rough_room_differs_and_names_its_model():
    """Control for the above: roughness 1 goes through the rough row and changes the image."""
    lambert = render(room(), settings(samples=64, seed=3), **SILENT)
    rough = render(room(1.0), settings(samples=64, seed=3), **SILENT)
    assert rough.stats["effects"]["rough_diffuse"]
    assert "energy-preserving" in rough.stats["effects_reason"]["rough_diffuse"]
    assert not np.array_equal(lambert.image, rough.image)


def white_rough_sphere(cycles_version, roughness=1.0):
    mats = [Material("Clay", DIFFUSE, (1.0, 1.0, 1.0), diffuse_roughness=roughness)]
    camera = Camera.look_at((0, -40.0, 0), (0, 0, 0), up=(0, 0, 1), lens=720.0)     # nearly orthographic
    return Scene(camera, mats, spheres=[Sphere("Ball", (0, 0, 0), 1.0, 0)], background=(1.0, 1.0, 1.0),
                 resolution=(32, 32), cycles_version=cycles_version)


def sphere_pixels(result):
    """(red values, their variances, mu at each pixel centre) of the pixels well inside the
    sphere's outline (the view spans 2.0 x 2.0 at the sphere: 36 mm sensor x 40 / 720)."""
    half = 36.0 * 40.0 / 720.0 / 2.0
    x = (np.arange(32) + 0.5) / 32 * 2 * half - half
    r2 = x[None, :] ** 2 + x[:, None] ** 2
    inside = r2 < 0.8 ** 2
    mu = np.sqrt(np.clip(1.0 - r2, 0.0, 1.0))
    return (result.image[..., 0][inside].astype(np.float64), result.variance[..., 0][inside].astype(np.float64),
            mu[inside])


@pytest.mark.parametrize("version, model", [((4, 3), "energy-preserving"), ((5, 0), "energy-preserving"),
                                            ((3, 6), "3.x"), ((4, 2), "3.x")])
def test_white_furnace_per_cycles_version(version, model):
    result = render(white_rough_sphere(version), settings(samples=128, seed=4, max_depth=2), **SILENT)
    assert model in result.stats["effects_reason"]["rough_diffuse"]
    value, var, mu = sphere_pixels(result)
    se = np.sqrt(var.sum()) / len(value)
    a, b = fon_coefficients(np.array(1.0))
    single = fon_albedo(mu, a, b)                        # the 3.x lobe's albedo at each pixel
    expected = 1.0 if model == "energy-preserving" else single.mean()
    other = single.mean() if model == "energy-preserving" else 1.0
    assert se < 0.002, se
    assert abs(value.mean() - expected) < 4 * se + 0.002, (value.mean(), expected, se)
    assert abs(value.mean() - other) > 0.05, (value.mean(), other)         # the control: the other model
    if model == "3.x":                       # pixel by pixel the closed form (within 4 standard errors)
        assert np.all(np.abs(value - single) < 4 * np.sqrt(var) + 0.01)
