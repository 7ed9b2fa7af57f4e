"""A Sky Texture's sun disc and its baked sky are picked as Cycles' sun-guided sky
(engine/lights/light_set.py LightSet.distant_weights, SKY_MAP_WEIGHT): the sky's light samples
drop to 0.2 x its share of the pair's flux, the disc takes the rest.

* the selection probabilities follow that rule (other suns keep their flux share; without the
  sky_disc flag the pair is picked by flux, the control);
* a diffuse floor under the image sky and the disc renders its exact radiance rho/pi (E_sun cos +
  E_sky) within the pixels' noise with and without the rule (direct light only: light samples and
  BSDF samples combined by MIS with world_pdf), with less noise with it; the control, densities and
  MIS weights from the old probabilities while drawing with the new ones, is biased and fails.
"""
import numpy as np
import pytest

from engine.lights.environment import EnvironmentMap, equirectangular_to_direction
from engine.lights.light_set import LightSet
from engine.lights.selection import PowerSelection
from engine.scene.model import Camera, Environment, Material, Quad, Scene, SunLight
from engine.scene.textures import ImageTexture

ALBEDO = 0.8
SUN_TRAVEL = np.array([0.5, 0.2, -0.8])            # the direction the sunlight travels
SUN_E = (3.0, 2.8, 2.5)


def sky(h=16, w=32):
    """A sky brighter near the horizon, with a bright patch high up (where the MIS weights matter),
    over a dim ground; the sun is the separate disc."""
    v = (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    elevation = (0.5 - v)[:, None] * np.pi
    rows = np.where(elevation > 0, 0.2 + 0.3 * np.exp(-4 * elevation), 0.05) * (1.0 + 0.3 * np.cos(2 * np.pi * u))
    rows[2:4, 4:8] = 4.0
    return np.stack([rows * 0.8, rows * 0.9, rows * 1.1], axis=-1).astype(np.float32)


def floor_scene(sky_disc, other_sun=False, resolution=(8, 8)):
    mats = [Material("Floor", color=(ALBEDO,) * 3)]
    suns = [SunLight("Disc", tuple(SUN_TRAVEL), SUN_E, 0.02, sky_disc=sky_disc)]
    if other_sun:
        suns.append(SunLight("Lamp sun", (-0.3, 0.1, -1.0), (0.5, 0.5, 0.5)))
    return Scene(Camera.look_at((0, 0, 2.0), (0, 0, 0), up=(0.0, 1.0, 0.0), lens=100.0), mats,
                 quads=[Quad("Floor", np.array([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]], float), 0)],
                 suns=suns, resolution=resolution,
                 textures=[ImageTexture("sky", pixels=sky(), colorspace="Linear", is_float=True)],
                 environment=Environment(0, interpolation="Closest"))


def exact_floor_radiance():
    """rho / pi x (the sun's E cos + the Closest-interpolated sky's irradiance on an up-facing
    floor, a fine midpoint sum over its texels), per channel."""
    m = EnvironmentMap(Environment(0, interpolation="Closest"), sky(), False)
    h, w = m.pixels.shape[:2]
    k = 8
    uu, vv = np.meshgrid((np.arange(w * k) + 0.5) / (w * k), (np.arange(h * k) + 0.5) / (h * k))
    d, s = equirectangular_to_direction(uu.ravel(), vv.ravel())
    weight = s * (2 * np.pi * np.pi) / (w * k * h * k)
    e_sky = (m.radiance(d) * np.maximum(d[2], 0.0) * weight).sum(axis=1)
    to_sun = -SUN_TRAVEL / np.linalg.norm(SUN_TRAVEL)
    return ALBEDO / np.pi * (np.asarray(SUN_E) * to_sun[2] + e_sky)


def test_the_pair_is_picked_as_cycles_sun_guided_sky():
    flux = LightSet(floor_scene(False, other_sun=True), world=True)
    guided = LightSet(floor_scene(True, other_sun=True), world=True)
    p_flux, p = flux.distant.selection.prob, guided.distant.selection.prob
    disc, other, env = 0, 1, 2                                          # the suns, then the world
    power = flux.distant_power
    assert np.allclose(p_flux, power / power.sum(), rtol=1e-12)
    pair = power[disc] + power[env]
    assert p[env] == pytest.approx(LightSet.SKY_MAP_WEIGHT * power[env] / power.sum(), rel=1e-12)
    assert p[disc] == pytest.approx((pair - LightSet.SKY_MAP_WEIGHT * power[env]) / power.sum(), rel=1e-12)
    assert p[other] == pytest.approx(p_flux[other], rel=1e-12)        # the lamp sun keeps its share
    assert abs(p_flux[env] - p[env]) > 0.05                             # control: the rule changes it


def render_floor(sky_disc, samples=64, seed=1):
    from engine.api import render
    from engine.core.settings import RenderSettings
    settings = RenderSettings(samples=samples, max_depth=0, threads=1, seed=seed, backend="numpy")
    return np.asarray(render(floor_scene(sky_disc), settings, log=lambda *a: None).image, float)[..., :3]


def z_score(image, exact):
    """Per channel: (the pixels' mean - exact) / its standard error (the pixels are independent
    estimates of one value: the floor's radiance does not depend on where)."""
    px = image.reshape(-1, 3)
    return (px.mean(axis=0) - exact) / (px.std(axis=0, ddof=1) / np.sqrt(len(px)))


@pytest.fixture(scope="module")
def renders():
    return {flag: render_floor(flag) for flag in (False, True)}


def test_the_floor_converges_to_its_radiance_with_less_noise(renders):
    exact = exact_floor_radiance()
    for flag, image in renders.items():
        assert np.abs(z_score(image, exact)).max() < 4.0, (flag, z_score(image, exact))
    noise = {flag: image.reshape(-1, 3).std(axis=0).mean() for flag, image in renders.items()}
    assert noise[True] < 0.7 * noise[False], noise


def test_control_densities_with_the_old_probabilities_are_biased(monkeypatch):
    """Drawing the pair with the guided probabilities but dividing by (and weighting MIS with) the
    flux probabilities: the floor is off by many standard errors."""
    groups = LightSet._groups

    def old_densities(self, *args):
        groups(self, *args)
        self.distant.selection.prob = PowerSelection(self.distant_power).prob    # the draw's cdf stays
    monkeypatch.setattr(LightSet, "_groups", old_densities)
    assert np.abs(z_score(render_floor(True), exact_floor_radiance())).max() > 6.0
