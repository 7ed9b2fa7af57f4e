"""A spot light's caustic photons (sample_blends/spot_light.blend's mirror-ball caustic): the ceiling
over a flat mirror gets the mirrored spot's irradiance R I a(theta) cos / d^2
(tests/integrators/photons/scenes.py), in the cone's core and in its blend, with the spot on the
mirror's normal and rotated off it, with and without a radius.  The controls are emissions that are
wrong in one way: a spot's direction pdf 5 % off, the blend left out of the photons' weight (a hard
edge), the cone kept on the unrotated axis.  And the same over a mirror ball (the sample scene's
setting), against the ball's ring-to-ring Jacobian."""
from __future__ import annotations

import numpy as np
import pytest

from engine.lights.points import PointLights
from engine.sampling.warps import orthonormal_basis
from tests.integrators.photons.scenes import (ball_spot_irradiance, ceiling_points_of, mirrored_spot_irradiance,
                                              off_the_ball, spot_falloff, spot_over_mirror, spot_over_mirror_ball)
from tests.integrators.photons.test_caustic_photons import ceiling_irradiance, prepared

OFF_AXIS = (0.3, 0.2, -1.0)
CASES = {                                        # (size, blend, axis, radius)
    "on axis, 60 deg, blend 0.3": (np.radians(60.0), 0.3, (0.0, 0.0, -1.0), 0.0),
    # as sample_blends/spot_light.blend's spot: 30 deg, blend 0.3, radius 0.05, aimed off the normal
    "rotated, 30 deg, blend 0.3, radius 0.05": (np.radians(30.0), 0.3, OFF_AXIS, 0.05),
}


def cone_points(size, blend, axis, region, n_theta=40, n_phi=24):
    """Ceiling points whose spot direction lies in the cone's core (a = 1, clear of the blend by a
    photon radius) or in the middle of its blend (0.2 <= a <= 0.8)."""
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    half = 0.5 * size
    theta, phi = np.meshgrid(np.linspace(0.0, half, n_theta), np.linspace(0.0, 2 * np.pi, n_phi, endpoint=False))
    t1, t2 = (v[:, 0] for v in orthonormal_basis(axis.reshape(3, 1)))
    w = (np.cos(theta).ravel() * axis[:, None] + np.sin(theta).ravel() * (np.cos(phi).ravel() * t1[:, None]
                                                                         + np.sin(phi).ravel() * t2[:, None]))
    a = spot_falloff(w, size, blend, axis)
    inner = np.arccos(np.cos(half) + (1.0 - np.cos(half)) * blend)        # where the blend begins
    keep = (theta.ravel() < inner - 0.06) if region == "core" else ((a >= 0.2) & (a <= 0.8))
    return ceiling_points_of(w[:, keep])


def wrong_emission(wrong, monkeypatch):
    if wrong is not None:
        real = PointLights.sample_emission

        def emission(self, *args, **kw):
            saved = self.spot_width.copy(), self.spot_axis.copy()
            if wrong == "hard edge":
                self.spot_width[:] = 0.0
            if wrong == "unrotated axis":
                self.spot_axis[:] = np.array([[0.0], [0.0], [-1.0]])
            e = real(self, *args, **kw)
            self.spot_width[:], self.spot_axis[:] = saved
            if wrong == "pdf 5 %":
                e.pdf_dir = e.pdf_dir / 1.05
            return e
        monkeypatch.setattr(PointLights, "sample_emission", emission)


def spot_error(case, region, wrong=None, monkeypatch=None):
    size, blend, axis, radius = CASES[case]
    wrong_emission(wrong, monkeypatch)
    photons = prepared(spot_over_mirror(size, blend, axis, radius), photons_per_pass=40_000, photon_radius=0.02,
                       seed=5).tracer.photons
    points = cone_points(size, blend, axis, region)
    estimate = ceiling_irradiance(photons, points, 8)
    return estimate.mean() / mirrored_spot_irradiance(points, size, blend, axis).mean() - 1.0


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("region", ["core", "blend"])
def test_the_ceiling_gets_the_mirrored_spots_irradiance(case, region):
    """Within 2 % in the core, 3 % in the middle of the blend (the disk estimate's bias where the
    falloff bends)."""
    assert abs(spot_error(case, region)) < (0.02 if region == "core" else 0.03)


@pytest.mark.parametrize("wrong, case, region", [
    ("pdf 5 %", "on axis, 60 deg, blend 0.3", "core"),
    ("hard edge", "rotated, 30 deg, blend 0.3, radius 0.05", "blend"),
    ("unrotated axis", "rotated, 30 deg, blend 0.3, radius 0.05", "core"),
])
def test_control_a_wrong_spot_emission_fails(wrong, case, region, monkeypatch):
    assert abs(spot_error(case, region, wrong, monkeypatch)) > (0.02 if region == "core" else 0.03)


BALL_SPOT = (np.radians(40.0), 0.3, (0.15, 0.1, -1.0))     # rotated off the ball's axis; the cone within the ball


def ball_error(wrong=None, monkeypatch=None):
    """The photons' irradiance over the ceiling points lit by the cone's core off the ball, relative
    to ball_spot_irradiance's."""
    size, blend, axis = BALL_SPOT
    wrong_emission(wrong, monkeypatch)
    theta, phi = (g.ravel() for g in np.meshgrid(np.linspace(0.02, 0.3, 30), np.linspace(0.0, 2 * np.pi, 24,
                                                                                        endpoint=False)))
    core = spot_falloff(off_the_ball(theta, phi)[0], size, blend, axis) == 1.0
    points, irradiance = ball_spot_irradiance(theta[core], phi[core], size, blend, axis)
    photons = prepared(spot_over_mirror_ball(size, blend, axis), photons_per_pass=40_000, photon_radius=0.02,
                       seed=5).tracer.photons
    return ceiling_irradiance(photons, points, 8).mean() / irradiance.mean() - 1.0


def test_the_ceiling_gets_the_spots_light_off_a_mirror_ball():
    assert abs(ball_error()) < 0.02


def test_control_off_the_ball_a_spot_pdf_off_by_five_percent_fails(monkeypatch):
    assert abs(ball_error("pdf 5 %", monkeypatch)) > 0.02
