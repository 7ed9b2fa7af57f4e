"""The microfacet reflection BSDF (engine/materials/glossy.py, microfacet.py): χ² of the visible-normal
samplers, sampled pdf = evaluated pdf, weight = eval / pdf, reciprocity, the albedo tables against
published values, and white furnaces with and without energy compensation; each with a control that
fails (a wrong pdf, a separable G2, no compensation)."""
from types import SimpleNamespace

import numpy as np
import pytest

from engine.materials import albedo_tables
from engine.materials.glossy import MicrofacetReflection
from engine.materials.microfacet import g1, g2_separable
from engine.materials.protocol import ShadingPoint
from tests.chi_square import ALPHA, sphere_chi2

NORMAL = np.array([0.0, 0.0, 1.0])
TANGENT = np.array([1.0, 0.0, 0.0])


def material(roughness=0.5, anisotropy=0.0, distribution="ggx", fresnel="none", multiscatter=False, **kw):
    return SimpleNamespace(name="G", ior=kw.pop("ior", 1.5), roughness=roughness, anisotropy=anisotropy,
                           distribution=distribution, fresnel=fresnel, multiscatter=multiscatter,
                           tangent=tuple(TANGENT), rotation=kw.pop("rotation", 0.0), **kw)


def hits(wo, n, color=1.0):
    def tile(v):
        return np.tile(np.asarray(v, dtype=np.float64)[:, None], (1, n))
    return ShadingPoint(tile(wo), tile(NORMAL), tile(NORMAL), tile(NORMAL), np.full((3, n), color),
                        np.zeros(n, dtype=np.int64))


def incidence(mu, phi=0.3):
    s = np.sqrt(1.0 - mu * mu)
    return np.array([s * np.cos(phi), s * np.sin(phi), mu])


def zoomed(bsdf, wo, k):
    """(sample, pdf) of the BSDF's wi seen through a stereographic zoom by k about the mirror
    direction, so that narrow lobes spread over the χ² grid (the density carries the Jacobian)."""
    axis = np.array([-wo[0], -wo[1], wo[2]])
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    frame = np.stack([e1, e2, axis])                    # rows: world -> lobe frame

    def warp(d, scale):
        local = frame @ d
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = np.sqrt(local[0] ** 2 + local[1] ** 2)
            t = rho / (1.0 + local[2])                    # tan(theta / 2)
            t2 = t * scale
            theta = 2.0 * np.arctan(t2)
            f = np.where(rho > 0, np.sin(theta) / rho, 0.0)
        out = np.stack([local[0] * f, local[1] * f, np.cos(theta)])
        return frame.T @ out

    def sample(u):
        n = u.shape[1]
        s = bsdf.sample(hits(wo, n), np.zeros(n), (u[0], u[1]))
        return np.where(s.pdf > 0, warp(s.wi, k), 0.0)

    def pdf(d):
        original = warp(d, 1.0 / k)
        c_new = (frame @ d)[2]
        c_old = (frame @ original)[2]
        jac = ((1.0 + c_old) / (1.0 + c_new)) ** 2 / (k * k)         # d omega / d omega' = cos^4 ratio / k^2
        return bsdf.pdf(hits(wo, d.shape[1]), original) * jac
    return sample, pdf


CASES = [(0.02, 0.0, 0.9), (0.25, 0.0, 0.9), (1.0, 0.0, 0.9), (0.25, 0.0, 0.1), (1.0, 0.0, 0.1),
         (0.4, 0.7, 0.6), (0.4, -0.5, 0.15)]


@pytest.mark.parametrize("distribution", ["ggx", "beckmann"])
@pytest.mark.parametrize("roughness,anisotropy,mu", CASES)
def test_visible_normal_sampler_matches_its_pdf(distribution, roughness, anisotropy, mu):
    """The expected counts integrate the density by the midpoint rule on 32 x 32 sub-cells per
    cell: with 8 x 8 the narrow anisotropic Beckmann lobes (Gaussian slopes, alpha_y = 0.08 at
    (0.4, -0.5)) were integrated too coarsely, p < 1e-15 at 1M samples for a right sampler,
    while 32 x 32 gives p = 0.72 (mu = 0.5) and 0.58 (mu = 0.15) there."""
    bsdf = MicrofacetReflection([material(roughness, anisotropy, distribution)], None)
    zoom = max(1.0, 0.5 / roughness ** 2)
    sample, pdf = zoomed(bsdf, incidence(mu), zoom)
    p, dof = sphere_chi2(sample, pdf, n=100_000, seed=7, refine=32)
    assert dof > 50 and p > ALPHA, (p, dof)


def test_chi2_rejects_the_sampler_against_another_roughness():
    """Control: the pdf of roughness 0.27 for samples of roughness 0.25."""
    wo = incidence(0.9)
    sample, _ = zoomed(MicrofacetReflection([material(0.25)], None), wo, 16.0)
    _, wrong = zoomed(MicrofacetReflection([material(0.27)], None), wo, 16.0)
    assert sphere_chi2(sample, wrong, n=100_000, seed=7, refine=32)[0] < 1e-6


@pytest.mark.parametrize("fresnel", ["none", "dielectric", "conductor", "f82", "interpolated"])
@pytest.mark.parametrize("distribution,multiscatter", [("ggx", False), ("ggx", True), ("beckmann", False)])
def test_sample_agrees_with_eval_and_pdf(fresnel, distribution, multiscatter):
    bsdf = MicrofacetReflection([material(0.45, 0.3, distribution, fresnel, multiscatter, edge_tint=(0.8, 0.9, 1.0),
                                          conductor_ior=(0.2, 0.9, 1.1), conductor_k=(3.0, 2.5, 2.0))], None)
    n = 20_000
    rng = np.random.default_rng(3)
    si = hits(incidence(0.4), n, color=0.7)
    s = bsdf.sample(si, np.zeros(n), (rng.random(n), rng.random(n)))
    f_cos, pdf = bsdf.eval(si, s.wi)
    ok = s.pdf > 0
    assert ok.mean() > 0.9
    assert np.allclose(pdf[ok], s.pdf[ok], rtol=1e-9)
    assert np.allclose(f_cos[:, ok] / pdf[ok], s.value[:, ok], rtol=1e-9)
    assert np.allclose(bsdf.pdf(si, s.wi), pdf)


@pytest.mark.parametrize("distribution", ["ggx", "beckmann"])
def test_uncompensated_lobe_is_reciprocal(distribution):
    bsdf = MicrofacetReflection([material(0.6, 0.4, distribution, "dielectric")], None)
    rng = np.random.default_rng(4)
    n = 2000
    a = rng.normal(size=(3, n))
    b = rng.normal(size=(3, n))
    a[2], b[2] = np.abs(a[2]), np.abs(b[2])
    a, b = a / np.linalg.norm(a, axis=0), b / np.linalg.norm(b, axis=0)

    def f(wo, wi):
        si = hits(NORMAL, n)
        si.wo = wo
        f_cos, _ = bsdf.eval(si, wi)
        return f_cos / wi[2]
    assert np.allclose(f(a, b), f(b, a), rtol=1e-10)


ORACLE = {0.5: ((1.0, 0.915), (0.5, 0.857), (0.1, 0.892), "avg", 0.882),
          1.0: ((1.0, 0.307), (0.5, 0.451), (0.1, 0.761), "avg", 0.409)}


@pytest.mark.parametrize("roughness", [0.5, 1.0])
def test_albedo_estimator_and_tables_match_published_values(roughness):
    *points, _, e_avg = ORACLE[roughness]
    for mu, expected in points:
        assert abs(albedo_tables.estimate_albedo(roughness, mu, 512, seed=11) - expected) < 0.002
        assert abs(float(albedo_tables.albedo(roughness, mu)) - expected) < 0.002
    assert abs(float(albedo_tables.average_albedo(roughness)) - e_avg) < 0.002


def furnace(bsdf, mu, n=400_000, seed=5, color=1.0):
    rng = np.random.default_rng(seed)
    s = bsdf.sample(hits(incidence(mu), n, color), np.zeros(n), (rng.random(n), rng.random(n)))
    return float(s.value[0].mean()), float(s.value[0].std() / np.sqrt(n))


def hemisphere_average(bsdf, nodes=16):
    x, w = np.polynomial.legendre.leggauss(nodes)
    return sum(wk * (x_k + 1.0) * furnace(bsdf, 0.5 * (x_k + 1.0), n=40_000)[0] * 0.5
               for x_k, wk in zip(x, w))


@pytest.mark.parametrize("roughness,loss", [(0.5, 0.118), (1.0, 0.591)])
def test_white_furnace_uncompensated_loses_one_minus_e_avg(roughness, loss):
    average = hemisphere_average(MicrofacetReflection([material(roughness)], None))
    assert abs((1.0 - average) - loss) < 0.003, average


@pytest.mark.parametrize("roughness", [0.25, 0.5, 1.0])
@pytest.mark.parametrize("mu", [1.0, 0.5, 0.1])
def test_white_furnace_compensated_reads_one(roughness, mu):
    value, err = furnace(MicrofacetReflection([material(roughness, multiscatter=True)], None), mu)
    assert abs(value - 1.0) < 0.005 and err < 0.002, (value, err)     # 2 sigma or more


def test_furnace_controls_fail():
    """No compensation and a separable G2 both lose energy beyond the tolerance at roughness 1."""
    plain = furnace(MicrofacetReflection([material(1.0, multiscatter=False)], None), 0.5)[0]
    assert plain < 0.5
    n = 100_000
    bsdf = MicrofacetReflection([material(1.0)], None)
    rng = np.random.default_rng(6)
    si = hits(incidence(0.5), n)
    s = bsdf.sample(si, np.zeros(n), (rng.random(n), rng.random(n)))
    ok = s.pdf > 0
    wo, wi = si.wo[:, ok], s.wi[:, ok]
    separable = (g2_separable(wo, wi, 1.0, 1.0) / g1(wo, 1.0, 1.0)).sum() / n
    assert abs(separable - s.value[0].mean()) > 0.01                  # a different (darker) albedo
    assert separable < s.value[0].mean()


def test_compensated_colour_darkens_as_cycles_multi_bounce_fresnel():
    """A tinted lobe (F = 0.5) reads E (1 + F_ms (1 - E) / E) < 1: F_ms = F E_avg / (1 - F (1 - E_avg))."""
    mu, roughness = 0.5, 1.0
    value, err = furnace(MicrofacetReflection([material(roughness, multiscatter=True)], None), mu, color=0.5)
    e, e_avg = float(albedo_tables.albedo(roughness, mu)), float(albedo_tables.average_albedo(roughness))
    f_ms = 0.5 * e_avg / (1.0 - 0.5 * (1.0 - e_avg))
    assert abs(value - 0.5 * e * (1.0 + f_ms * (1.0 - e) / e)) < 4 * err + 1e-3
