"""Cycles' two rough diffuse models (engine/materials/oren_nayar.py) against the BSDF protocol,
their samplers by χ², and their energy: Cycles 4.3+'s energy-preserving Oren-Nayar passes the
white furnace at every incidence, Cycles 3.4's Oren-Nayar loses exactly 1 - E(mu) of the closed
form (written here again in the EON paper's notation, independently of the module's).  Controls: a
flipped B term, a missing multiple-scatter lobe and a wrong pdf fail the same checks."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.materials.lambert import Lambertian
from engine.materials.oren_nayar import EnergyPreservingOrenNayar, OrenNayar34, fon_coefficients
from engine.materials.protocol import BSDFFlags, ShadingPoint
from tests.chi_square import ALPHA, sphere_chi2
from tests.materials.test_bsdf_contract import hits, reciprocal, sample_matches_eval, uniforms, unit, upper_directions

MODELS = (OrenNayar34, EnergyPreservingOrenNayar)
INCIDENCES = (1.0, 0.8, 0.5, 0.3, 0.1, 0.02)        # cos theta_o


def make(cls, *roughness):
    return cls([], RenderSettings(), roughness=list(roughness))


# -- independent references (the EON paper's notation: A, B of FON, r the roughness) ---------------
def fon_albedo_reference(mu, r):
    """E_FON(mu): Portsmouth, Kutz and Hill 2024 (EON), the FON directional albedo."""
    af = 1.0 / (1.0 + (0.5 - 2.0 / (3.0 * np.pi)) * r)
    bf = r * af
    si = np.sqrt(1.0 - mu * mu)
    g = si * (np.arccos(mu) - si * mu) + (2.0 / 3.0) * ((si / mu) * (1.0 - si ** 3) - si)
    return af + bf / np.pi * g


def fon_average_reference(r):
    """E_avg of FON (the EON paper): A (1 + (2/3 - 28 / (15 pi)) r)."""
    af = 1.0 / (1.0 + (0.5 - 2.0 / (3.0 * np.pi)) * r)
    return af * (1.0 + (2.0 / 3.0 - 28.0 / (15.0 * np.pi)) * r)


def cycles_eon_albedo_reference(mu, r, rho):
    """Cycles 4.3's albedo for colour rho: rho E + rho rho_ms (1 - E), rho_ms of the EON paper
    (Cycles multiplies the paper's multiple-scatter lobe by its closure weight rho once more)."""
    e, e_avg = fon_albedo_reference(mu, r), fon_average_reference(r)
    rho_ms = rho * rho * e_avg / (1.0 - rho * (1.0 - e_avg))
    return rho * e + rho * rho_ms * (1.0 - e)


# -- measurements -----------------------------------------------------------------------------------
def viewer(mu, n, rho=1.0, material=0):
    """n hits on the plane z = 0 seen from cos theta_o = mu."""
    nrm = np.tile([[0.0], [0.0], [1.0]], (1, n))
    wo = np.tile([[np.sqrt(1.0 - mu * mu)], [0.0], [mu]], (1, n))
    return ShadingPoint(wo, nrm, nrm, nrm, np.full((3, n), rho), np.full(n, material, dtype=np.int64))


def quadrature_albedo(bsdf, mu, rho=1.0, nz=600, nphi=300):
    """int f cos d(omega) over the hemisphere by the midpoint rule in (cos theta_i, phi)."""
    z = (np.arange(nz) + 0.5) / nz
    phi = (np.arange(nphi) + 0.5) * (2.0 * np.pi / nphi)
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    r = np.sqrt(1.0 - zz * zz)
    wi = np.stack([r * np.cos(pp), r * np.sin(pp), zz]).reshape(3, -1)
    f_cos = bsdf.eval(viewer(mu, wi.shape[1], rho), wi)[0][0]
    return f_cos.sum() * (1.0 / nz) * (2.0 * np.pi / nphi)


def sampled_albedo(bsdf, mu, n=100_000, seed=0, rho=1.0):
    """(mean, standard error) of the sample weights f cos / pdf: the albedo the path tracer sees."""
    rng = np.random.default_rng(seed)
    value = bsdf.sample(viewer(mu, n, rho), rng.random(n), (rng.random(n), rng.random(n))).value[0]
    return value.mean(), value.std() / np.sqrt(n)


def passes_furnace(bsdf, tolerance=0.005):
    """Albedo 1 -> directional albedo 1 +- tolerance at every incidence, by quadrature of eval
    and by the sampler's weights."""
    for mu in INCIDENCES:
        mean, _ = sampled_albedo(bsdf, mu, seed=int(mu * 100))
        if abs(quadrature_albedo(bsdf, mu) - 1.0) > tolerance or abs(mean - 1.0) > tolerance:
            return False
    return True


def loses_the_fon_energy(bsdf, r):
    """The albedo is the closed-form E_FON(mu) at every incidence: quadrature within 1e-3, the
    sampler's mean within 4 standard errors."""
    for mu in INCIDENCES:
        expected = fon_albedo_reference(mu, r)
        mean, se = sampled_albedo(bsdf, mu, seed=int(mu * 100) + 1)
        if abs(quadrature_albedo(bsdf, mu) - expected) > 1e-3 or abs(mean - expected) > 4.0 * se:
            return False
    return True


# -- the protocol's contract -------------------------------------------------------------------------
@pytest.mark.parametrize("cls", MODELS)
@pytest.mark.parametrize("roughness", [0.3, 1.0])
def test_sample_is_eval_over_pdf_and_reciprocal(cls, roughness):
    bsdf = make(cls, roughness)
    assert bsdf.flags == BSDFFlags.DIFFUSE | BSDFFlags.REFLECTION and bsdf.lambert_albedo(hits(1)) is None
    assert sample_matches_eval(bsdf, hits(21), 21)
    assert reciprocal(bsdf, 22)
    s = bsdf.sample(hits(23), *uniforms(23))
    assert np.all(s.flags == BSDFFlags.DIFFUSE | BSDFFlags.REFLECTION)
    assert np.all((s.wi * hits(23).n).sum(axis=0) >= 0.0) and np.all(np.isfinite(s.value))


@pytest.mark.parametrize("cls", MODELS)
def test_no_albedo_above_one_and_nothing_below_the_surface(cls):
    """Colour (0.8, 0.5, 0.2) and white, roughness 1: every incidence reflects at most 1 (the
    weight of one sample may exceed 1: f is not constant), and directions below get 0."""
    bsdf = make(cls, 1.0)
    for rho in (1.0, 0.8):
        assert max(quadrature_albedo(bsdf, mu, rho) for mu in INCIDENCES) <= 1.0 + 1e-3
    si = hits(24)
    f_cos, pdf = bsdf.eval(si, -upper_directions(si, 24))
    assert np.all(f_cos == 0.0) and np.all(pdf == 0.0)


@pytest.mark.parametrize("cls", MODELS)
def test_roughness_zero_is_the_lambertian_bsdf(cls):
    """Roughness 0 scatters as engine/materials/lambert.py (Cycles sets up its diffuse closure):
    eval, pdf, the sampled directions and the weight rho exactly; and the rough formula tends to
    Lambert as roughness -> 0 (1e-13: within 1e-12)."""
    lambert = Lambertian([], RenderSettings())
    si = hits(25)
    wi = upper_directions(si, 25)
    for got, want in zip(make(cls, 0.0).eval(si, wi), lambert.eval(si, wi)):
        assert np.allclose(got, want, rtol=0, atol=1e-12)
    u_lobe, u = uniforms(25)
    s, t = make(cls, 0.0).sample(si, u_lobe, u), lambert.sample(si, u_lobe, u)
    assert np.array_equal(s.wi, t.wi) and np.array_equal(s.value, t.value) and np.array_equal(s.pdf, t.pdf)
    almost = make(cls, 1e-13).eval(si, wi)[0]
    assert np.allclose(almost, lambert.eval(si, wi)[0], rtol=0, atol=1e-12)


def test_each_hit_takes_its_own_materials_roughness():
    """Materials 0 (roughness 0) and 1 (roughness 1) in one wavefront: each hit is the model of its
    material alone."""
    si = hits(26)
    si.material = np.arange(len(si)) % 2
    wi = upper_directions(si, 26)
    mixed = make(EnergyPreservingOrenNayar, 0.0, 1.0).eval(si, wi)[0]
    smooth = make(EnergyPreservingOrenNayar, 0.0, 0.0).eval(si, wi)[0]
    rough = make(EnergyPreservingOrenNayar, 1.0, 1.0).eval(si, wi)[0]
    assert np.array_equal(mixed[:, 0::2], smooth[:, 0::2]) and np.array_equal(mixed[:, 1::2], rough[:, 1::2])
    assert not np.allclose(smooth[:, 1::2], rough[:, 1::2])


# -- the samplers: χ² against their own pdf ------------------------------------------------------------
NORMAL = unit(np.array([[0.3], [-0.5], [0.81]]))[:, 0]


def tilted(n, wo):
    normal = np.tile(NORMAL[:, None], (1, n))
    return ShadingPoint(np.tile(wo[:, None], (1, n)), normal, normal, normal, np.full((3, n), 0.7),
                        np.zeros(n, dtype=np.int64))


def chi2_of(bsdf, wo, pdf=None, seed=5):
    def sample(u):
        return bsdf.sample(tilted(u.shape[1], wo), np.zeros(u.shape[1]), (u[0], u[1])).wi

    def density(d):
        return (pdf or bsdf.pdf)(tilted(d.shape[1], wo), d)
    return sphere_chi2(sample, density, seed=seed)


@pytest.mark.parametrize("cls", MODELS)
@pytest.mark.parametrize("wo", [np.array([0.0, 0.6, 0.8]), unit(np.array([[1.0], [0.2], [0.05]]))[:, 0]])
def test_sampler_matches_its_pdf(cls, wo):
    p, dof = chi2_of(make(cls, 0.7), wo)
    assert dof > 100 and p > ALPHA, (p, dof)


def test_chi2_rejects_a_sampler_against_the_other_models_pdf():
    """Control: Cycles 3.4 samples uniformly, 4.3 by the cosine; each fails the other's pdf."""
    wo = np.array([0.0, 0.6, 0.8])
    uniform, cosine = make(OrenNayar34, 0.7), make(EnergyPreservingOrenNayar, 0.7)
    assert chi2_of(uniform, wo, pdf=cosine.pdf)[0] < 1e-6
    assert chi2_of(cosine, wo, pdf=uniform.pdf)[0] < 1e-6


# -- energy --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("roughness", [0.5, 1.0])
def test_the_energy_preserving_model_passes_the_white_furnace(roughness):
    assert passes_furnace(make(EnergyPreservingOrenNayar, roughness))


@pytest.mark.parametrize("roughness", [0.5, 1.0])
def test_the_34_model_loses_exactly_the_fon_energy(roughness):
    """White, Cycles 3.4: the albedo is E_FON(mu) (12.6 % lost at normal incidence for roughness
    0.5, 22.3 % for 1; 0 at grazing), and the cosine-weighted average is the paper's E_avg."""
    bsdf = make(OrenNayar34, roughness)
    assert loses_the_fon_energy(bsdf, roughness)
    assert not passes_furnace(bsdf)
    mu = (np.arange(200) + 0.5) / 200
    average = 2.0 * np.mean([quadrature_albedo(bsdf, m, nz=200, nphi=100) * m for m in mu])
    assert abs(average - fon_average_reference(roughness)) < 1e-3


def test_the_published_figures():
    """The closed forms at the roughness the tests use: E_FON(1) = 0.8742 / 0.7765 and E_avg =
    0.9059 / 0.8328 at roughness 0.5 / 1 (the figures of docs/materials.md); FON's A of Cycles 3.4
    ((3 pi - 4) / 6) and of 4.3 (pi / 2 - 2 / 3) are one coefficient."""
    assert np.allclose([fon_albedo_reference(1.0 - 1e-12, r) for r in (0.5, 1.0)], [0.8742, 0.7765], atol=1e-4)
    assert np.allclose([fon_average_reference(r) for r in (0.5, 1.0)], [0.9059, 0.8328], atol=1e-4)
    a, b = fon_coefficients(np.array([1.0]))
    assert np.isclose(a[0], 1.0 / (np.pi + (3.0 * np.pi - 4.0) / 6.0), rtol=1e-15) and b[0] == a[0]


@pytest.mark.parametrize("rho", [0.5, 0.8])
def test_a_coloured_energy_preserving_surface_reflects_cycles_albedo(rho):
    """Colour rho < 1, roughness 1: rho E + rho rho_ms (1 - E) at every incidence (Cycles' weight
    times the EON lobe); the EON paper's rho E + rho_ms (1 - E) is brighter by (1 - rho) rho_ms (1 - E)."""
    bsdf = make(EnergyPreservingOrenNayar, 1.0)
    for mu in INCIDENCES:
        got = quadrature_albedo(bsdf, mu, rho)
        assert abs(got - cycles_eon_albedo_reference(mu, 1.0, rho)) < 1e-3, (mu, got)
    e, e_avg = fon_albedo_reference(1.0 - 1e-12, 1.0), fon_average_reference(1.0)
    paper = rho * e + rho * rho * e_avg / (1.0 - rho * (1.0 - e_avg)) * (1.0 - e)
    assert paper - quadrature_albedo(bsdf, 1.0, rho) > 5e-3


# -- controls: a wrong term fails the same checks ------------------------------------------------------
class FlippedB(OrenNayar34):
    """B's sign flipped: f_ss = a - b s / t."""
    def _f(self, si, wi, cos_i, sigma):
        a, b = fon_coefficients(sigma)
        return 2.0 * si.color * a - super()._f(si, wi, cos_i, sigma)


class SingleScatterOnly(EnergyPreservingOrenNayar):
    """The 4.3 model without its multiple-scatter lobe."""
    def _multiple_scatter(self, si, cos_i, cos_o, a, b):
        return 0.0


class UniformPdfCosineSampler(OrenNayar34):
    """Samples by the cosine but claims the uniform pdf."""
    def _sample_rough(self, u, n):
        return EnergyPreservingOrenNayar._sample_rough(self, u, n)


def test_the_checks_fail_wrong_terms():
    assert not loses_the_fon_energy(make(FlippedB, 1.0), 1.0)
    assert not passes_furnace(make(SingleScatterOnly, 1.0))
    assert chi2_of(make(UniformPdfCosineSampler, 0.7), np.array([0.0, 0.6, 0.8]))[0] < 1e-6
