"""Fresnel and Snell against reference numbers (docs/hard-cases.md S4-S6)."""
import numpy as np
import pytest

from engine.materials.fresnel import fresnel_exact, fresnel_schlick
from engine.materials.specular import reflect, refract, refract_cos


def fresnel(model, theta_deg, eta):
    cos_i = np.array([np.cos(np.radians(theta_deg))])
    eta = np.array([eta])
    cos_t, tir = refract_cos(cos_i, eta)
    return model(cos_i, cos_t, eta, tir)[0]


def test_exact_fresnel_reference_values():
    assert fresnel(fresnel_exact, 45.0, 1 / 1.5) == pytest.approx(0.050239911012, abs=1e-9)
    assert fresnel(fresnel_exact, 80.0, 1 / 1.5) == pytest.approx(0.387704354691473, abs=1e-9)


def test_schlick_reference_values():
    assert fresnel(fresnel_schlick, 45.0, 1 / 1.5) == pytest.approx(0.042069, abs=1e-6)
    assert fresnel(fresnel_schlick, 80.0, 1 / 1.5) == pytest.approx(0.409910, abs=1e-6)


def test_exact_fresnel_reciprocity():
    theta_i = 60.0
    theta_t = np.degrees(np.arcsin(np.sin(np.radians(theta_i)) / 1.5))
    assert fresnel(fresnel_exact, theta_i, 1 / 1.5) == pytest.approx(fresnel(fresnel_exact, theta_t, 1.5), abs=1e-12)


@pytest.mark.parametrize("model", [fresnel_exact, fresnel_schlick])
def test_total_internal_reflection_is_continuous_at_the_critical_angle(model):
    critical = np.degrees(np.arcsin(1 / 1.5))
    below = fresnel(model, critical - 1e-7, 1.5)
    assert below > 0.999
    assert fresnel(model, critical, 1.5) == pytest.approx(1.0, abs=1e-3)
    assert fresnel(model, critical + 1e-7, 1.5) == 1.0
    assert fresnel(model, 89.99, 1.5) == 1.0


@pytest.mark.parametrize("model", [fresnel_exact, fresnel_schlick])
def test_index_matched_interface_passes_straight_through(model):
    for theta in (0.0, 30.0, 89.9):
        assert fresnel(model, theta, 1.0) == 0.0
    d = np.array([[np.sin(0.5), 0.0, -np.cos(0.5)]])
    n = np.array([[0, 0, 1.0]])
    cos_i = -np.einsum("ij,ij->i", d, n)
    cos_t, _ = refract_cos(cos_i, np.array([1.0]))
    assert np.allclose(refract(d.T, n.T, cos_i, cos_t, np.array([1.0])).T, d, atol=1e-15)


def test_snell_law_and_unit_length():
    rng = np.random.default_rng(5)
    theta = rng.uniform(0, np.radians(89.9), 1000)
    d = np.stack([np.sin(theta), np.zeros_like(theta), -np.cos(theta)], axis=1)
    n = np.tile([0, 0, 1.0], (1000, 1))
    eta = np.full(1000, 1 / 1.5)
    cos_i = np.cos(theta)
    cos_t, tir = refract_cos(cos_i, eta)
    assert not tir.any()
    t = refract(d.T, n.T, cos_i, cos_t, eta).T             # directions as rows (3, N)
    assert np.allclose(np.linalg.norm(t, axis=1), 1, atol=1e-12)
    sin_t = np.hypot(t[:, 0], t[:, 1])
    assert np.abs(np.sin(theta) - 1.5 * sin_t).max() < 1e-12
    assert (t[:, 2] < 0).all()


def test_reflect_at_grazing_incidence():
    theta = np.radians(89.99)
    d = np.array([[np.sin(theta), 0, -np.cos(theta)]])
    r = reflect(d.T, np.array([[0, 0, 1.0]]).T).T
    assert r[0, 2] > 0 and np.linalg.norm(r) == pytest.approx(1.0, abs=1e-15)
