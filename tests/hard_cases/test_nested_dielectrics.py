"""Nested dielectrics (the report's §4 future work): glass inside glass.

With `nested_dielectrics` each path keeps a stack of the media it is inside, so an
inner sphere of the same IOR as the glass around it is an index-matched interface:
invisible.  Without it (the report's and Cycles' model: every surface against air) the
same inner sphere acts as a lens.
"""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.scene.model import DIFFUSE, GLASS, Camera, Material, Quad, Scene, Sphere

SILENT = dict(log=lambda *a: None)


def lens_scene(inner_ior=None):
    mats = [Material("Glass", GLASS, (1, 1, 1), ior=1.5), Material("Checker", DIFFUSE, (0.9, 0.1, 0.1)),
            Material("Inner", GLASS, (1, 1, 1), ior=inner_ior or 1.5)]
    wall = Quad("Wall", np.array([(-1.5, 2, -1.5), (1.5, 2, -1.5), (1.5, 2, 0), (-1.5, 2, 0)], float), 1)
    spheres = [Sphere("Outer", (0, 0, 0), 1.0, 0)]
    if inner_ior is not None:
        spheres.append(Sphere("Inner", (0, 0, 0), 0.6, 2))
    # A red strip below the horizon behind the ball, white background elsewhere: refraction moves it.
    return Scene(Camera.look_at((0, -4, 0), (0, 0, 0), lens=70), mats, spheres=spheres, quads=[wall],
                 background=(1, 1, 1), resolution=(16, 16))


def centre_mean(result):
    img, var = result.image[5:11, 5:11, 1], result.variance[5:11, 5:11, 1]
    return img.mean(), np.sqrt(var.sum()) / img.size


@pytest.mark.parametrize("seed", [1])
def test_index_matched_inner_sphere_is_invisible_with_nested_dielectrics(seed):
    settings = RenderSettings(samples=256, max_depth=16, nested_dielectrics=True, seed=seed, fresnel="exact")
    plain = render(lens_scene(None), settings, **SILENT)
    nested = render(lens_scene(1.5), settings, **SILENT)
    m0, s0 = centre_mean(plain)
    m1, s1 = centre_mean(nested)
    assert abs(m1 - m0) < 3.5 * np.hypot(s0, s1), (m0, m1, s0, s1)
    assert nested.stats["nonfinite_samples"] == 0


def test_without_nested_dielectrics_the_inner_sphere_is_a_lens():
    """Control: the same comparison fails in the air-interface model (the test can fail)."""
    settings = RenderSettings(samples=256, max_depth=16, nested_dielectrics=False, fresnel="exact")
    m0, s0 = centre_mean(render(lens_scene(None), settings, **SILENT))
    m1, s1 = centre_mean(render(lens_scene(1.5), settings, **SILENT))
    assert abs(m1 - m0) > 5 * np.hypot(s0, s1), (m0, m1, s0, s1)


ALWAYS_REFRACT = np.array([0.999])     # a lobe uniform of 0.999 refracts whenever F < 0.999


def test_water_in_glass_refracts_by_the_ior_ratio_and_the_stack_pushes_and_pops():
    from engine.materials.glass import SmoothGlass
    from engine.materials.media import MediumStack
    from engine.materials.protocol import BSDFFlags, ShadingPoint
    water = SmoothGlass([Material("Water", GLASS, (1, 1, 1), ior=1.33)],
                        RenderSettings(nested_dielectrics=True, fresnel="exact"))
    theta = np.radians(30.0)
    d = np.array([[np.sin(theta)], [0.0], [-np.cos(theta)]])   # rows: the ray comes from above
    n_out = np.array([[0.0], [0.0], [1.0]])                    # water surface normal
    stack = MediumStack(np.array([[1.5, 1.0, 1.0, 1.0]]), np.array([1]))   # the path is inside the glass
    tint = np.ones((3, 1))
    entering = ShadingPoint(-d, n_out, n_out, n_out, tint, np.zeros(1, dtype=np.int64), media=stack)
    s = water.sample(entering, ALWAYS_REFRACT, None)
    sin_t = np.hypot(s.wi[0, 0], s.wi[1, 0])
    assert s.flags[0] == BSDFFlags.DELTA | BSDFFlags.TRANSMISSION
    assert 1.5 * np.sin(theta) == pytest.approx(1.33 * sin_t, abs=1e-12)   # Snell with n1 = glass
    assert stack.depth[0] == 2 and stack.media[0, 1] == 1.33                # pushed: now in water
    # Leaving the water again (hitting its surface from inside): back into glass, popped.
    back = np.array([[np.sin(theta)], [0.0], [np.cos(theta)]])
    leaving = ShadingPoint(-back, -n_out, -n_out, n_out, tint, np.zeros(1, dtype=np.int64), media=stack)
    s2 = water.sample(leaving, ALWAYS_REFRACT, None)
    assert 1.33 * np.sin(theta) == pytest.approx(1.5 * np.hypot(s2.wi[0, 0], s2.wi[1, 0]), abs=1e-12)
    assert stack.depth[0] == 1 and s2.flags[0] & BSDFFlags.TRANSMISSION
