"""Point and spot lights' emitted rays aimed at target spheres (engine/lights/points.py
sample_emission with targets, engine/lights/aim.py): the flux the aimed rays carry into the targets
is the flux the unaimed rays carry there (the exact I x solid angle for a point without a radius and
one target), for a bare point, a disk light and a spot; controls: the targets not grown by the
light's radius, and a direction pdf 5 % off, fail."""
from __future__ import annotations

import numpy as np
import pytest

from engine.lights.aim import SphereTargets
from engine.lights.points import PointLights
from engine.scene.model import PointLight

N = 200_000


def flux_into(light, targets, aimed, seed=1, n=N):
    """(mean, standard error) of the flux (first channel) the rays of light 0 carry into any target:
    radiance |cos| / (pdf_pos pdf_dir) where the ray meets a target sphere ahead, else 0."""
    u = np.random.default_rng(seed).random((4, n))
    e = light.sample_emission(np.zeros(n, np.int64), *u, targets=targets if aimed else None)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = e.radiance[0] * np.abs((e.direction * e.normal).sum(axis=0)) / (e.pdf_pos * e.pdf_dir)
    w = np.where(np.isfinite(w), w, 0.0)
    hit = np.zeros(n, bool)
    for c, r in zip(targets.center.T, targets.radius):
        rel = c[:, None] - e.origin
        along = (rel * e.direction).sum(axis=0)
        hit |= (along > 0) & ((rel * rel).sum(axis=0) - along * along <= r * r)
    w = np.where(hit, w, 0.0)
    return w.mean(), w.std() / np.sqrt(n)


def lights(**kw):
    return PointLights([PointLight("L", (0.0, 0.0, 2.0), (3.0, 3.0, 3.0), **kw)])


TWO = SphereTargets([[0.3, 0.6], [0.0, 0.2], [0.0, -0.1]], [0.3, 0.25])


def test_a_bare_point_carries_i_times_the_solid_angle_into_one_target():
    one = SphereTargets([[0.3], [0.1], [0.0]], [0.4])
    d = np.linalg.norm(one.center[:, 0] - [0.0, 0.0, 2.0])
    cos_beta = np.sqrt(1.0 - (0.4 / d) ** 2)
    mean, se = flux_into(lights(), one, aimed=True)
    assert se < 1e-9 * mean and np.isclose(mean, 3.0 * 2.0 * np.pi * (1.0 - cos_beta), rtol=1e-9)


@pytest.mark.parametrize("kw", [{}, {"radius": 0.6}, {"radius": 0.05, "spot_size": 2.5, "spot_blend": 0.3,
                                                     "spot_direction": (0.1, 0.0, -1.0)}],
                         ids=["point", "disk", "spot"])
def test_aimed_rays_carry_the_unaimed_flux_into_the_targets(kw):
    light = lights(**kw)
    if "spot_size" in kw:
        assert light._aims(np.zeros(1, np.int64), TWO).all()        # the targets are narrower than its cone
    a, sa = flux_into(light, TWO, aimed=True)
    b, sb = flux_into(light, TWO, aimed=False, seed=2)
    assert abs(a - b) < 4.0 * np.hypot(sa, sb) and sa < 0.5 * sb       # the same flux, with less noise


def test_control_targets_not_grown_by_the_lights_radius_lose_flux(monkeypatch):
    light = lights(radius=0.6)
    real = PointLights._aimed
    monkeypatch.setattr(PointLights, "_aimed", lambda self, idx, u1, u2, targets: real(
        PointLights([PointLight("L", (0.0, 0.0, 2.0), (3.0, 3.0, 3.0))]), idx, u1, u2, targets))
    a, sa = flux_into(light, TWO, aimed=True)
    b, sb = flux_into(light, TWO, aimed=False, seed=2)
    assert a < b - 4.0 * np.hypot(sa, sb)


def test_control_a_direction_pdf_five_percent_off_fails(monkeypatch):
    real = PointLights._aimed

    def wrong(self, *a):
        direction, pdf = real(self, *a)
        return direction, pdf * 1.05
    monkeypatch.setattr(PointLights, "_aimed", wrong)
    one = SphereTargets([[0.3], [0.1], [0.0]], [0.4])
    exact = 3.0 * 2.0 * np.pi * (1.0 - np.sqrt(1.0 - 0.4 ** 2 / np.sum(np.subtract([0.3, 0.1, 0.0], [0, 0, 2.0]) ** 2)))
    mean, _ = flux_into(lights(), one, aimed=True)
    assert not np.isclose(mean, exact, rtol=0.02)


def test_a_spot_narrower_than_the_targets_keeps_its_cone():
    light = lights(spot_size=0.3, spot_direction=(0.0, 0.0, -1.0))
    assert not light._aims(np.zeros(1, np.int64), TWO).any()
    big = SphereTargets([[0.0], [0.0], [0.0]], [5.0])                  # holds the light: every direction
    assert not lights(spot_size=2.0)._aims(np.zeros(1, np.int64), big).any()
