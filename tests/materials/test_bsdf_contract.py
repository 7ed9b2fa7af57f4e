"""The BSDF protocol's contract (engine/materials/protocol.py) for every implementation.

Non-delta lobes: sample's value is eval / pdf at the sampled direction, sample's pdf is pdf(),
eval's f is reciprocal (f(wo, wi) = f(wi, wo)), and no sample gains energy (value <= 1 for
colours <= 1).  Delta lobes: eval and pdf are 0 for every given direction.  Each check is a
function that a broken BSDF fails (the controls at the end)."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.materials.glass import SmoothGlass
from engine.materials.glossy import MicrofacetReflection
from engine.materials.lambert import Lambertian
from engine.materials.mirror import PerfectMirror
from engine.materials.principled import PrincipledV2
from engine.materials.protocol import BSDFFlags, ShadingPoint, has_non_delta
from engine.materials.oren_nayar import RoughDiffuse
from engine.materials.table import KIND_CODE, NON_DELTA_KINDS, ROUGH_DIFFUSE, SCATTERING, MaterialTable
from engine.scene.model import DIFFUSE, GLASS, GLOSSY, MIRROR, PRINCIPLED, Material

N = 4000
MATERIALS = [Material("Diffuse", DIFFUSE, (0.8, 0.5, 0.2)), Material("Mirror", MIRROR, (0.9, 0.9, 0.9)),
             Material("Glass", GLASS, (1.0, 1.0, 1.0), ior=1.5)]
GLASS_ID = 2                                      # its material id (the IOR the glass BSDF reads)


def unit(rows):
    return rows / np.sqrt((rows * rows).sum(axis=0))


def hits(seed, n=N, color=(0.8, 0.5, 0.2), material=0, wo=None, normal_side=None):
    """n hits with random normals and random outgoing directions on the normal's side."""
    rng = np.random.default_rng(seed)
    nrm = unit(rng.normal(size=(3, n)))
    if wo is None:
        wo = unit(rng.normal(size=(3, n)))
        wo = wo * np.where((wo * nrm).sum(axis=0) < 0.0, -1.0, 1.0)
    outward = nrm if normal_side is None else nrm * normal_side
    return ShadingPoint(wo, nrm, nrm, outward, np.tile(np.asarray(color, float)[:, None], (1, n)),
                        np.full(n, material, dtype=np.int64))


def uniforms(seed, n=N):
    rng = np.random.default_rng(seed + 1000)
    return rng.random(n), (rng.random(n), rng.random(n))


def upper_directions(si, seed):
    rng = np.random.default_rng(seed + 2000)
    wi = unit(rng.normal(size=(3, len(si))))
    return wi * np.where((wi * si.n).sum(axis=0) < 0.0, -1.0, 1.0)


# -- the checks ------------------------------------------------------------------------------------
def sample_matches_eval(bsdf, si, seed):
    """value = eval / pdf and pdf = pdf() at every sampled direction of a non-delta lobe."""
    u_lobe, u = uniforms(seed, len(si))
    s = bsdf.sample(si, u_lobe, u)
    sampled = np.flatnonzero((s.flags & BSDFFlags.DELTA) == 0)
    assert len(sampled)
    at = si.take(sampled)
    wi = s.wi.take(sampled, axis=1)
    f_cos, pdf = bsdf.eval(at, wi)
    positive = pdf > 0
    return (np.allclose(s.pdf.take(sampled), bsdf.pdf(at, wi), rtol=1e-12, atol=0)
            and np.allclose(pdf, bsdf.pdf(at, wi), rtol=1e-12, atol=0)
            and np.allclose(s.value.take(sampled, axis=1)[:, positive], f_cos[:, positive] / pdf[positive],
                            rtol=1e-9, atol=0))


def reciprocal(bsdf, seed):
    """f(wo, wi) = f(wi, wo), with f = (f cos) / cos(wi) for directions on the normal's side."""
    si = hits(seed)
    wi = upper_directions(si, seed)
    swapped = ShadingPoint(wi, si.n, si.ng, si.normal, si.color, si.material)
    f_ab = bsdf.eval(si, wi)[0] / (wi * si.n).sum(axis=0)
    f_ba = bsdf.eval(swapped, si.wo)[0] / (si.wo * si.n).sum(axis=0)
    return np.allclose(f_ab, f_ba, rtol=1e-9, atol=0)


def conserves_energy(bsdf, seed, n=200_000):
    """Sampled values at most 1 (colours <= 1), and the albedo of eval, the integral of f cos
    over the sphere (uniform directions, 5 standard errors of slack), at most 1."""
    u_lobe, u = uniforms(seed)
    si = hits(seed, color=(1.0, 1.0, 1.0))
    s = bsdf.sample(si, u_lobe, u if has_non_delta(bsdf.flags) else None)
    if s.value.max() > 1.0 + 1e-12:
        return False
    one = hits(seed, n=1, color=(1.0, 1.0, 1.0))
    many = one.take(np.zeros(n, dtype=np.int64))
    wi = unit(np.random.default_rng(seed).normal(size=(3, n)))
    f_cos = bsdf.eval(many, wi)[0][0] * (4.0 * np.pi)           # uniform sphere pdf 1 / (4 pi)
    return f_cos.mean() <= 1.0 + 5.0 * f_cos.std() / np.sqrt(n)


def delta_has_no_density(bsdf, seed):
    """eval and pdf are 0 for any direction, the sampled one included."""
    si = hits(seed, material=GLASS_ID if isinstance(bsdf, SmoothGlass) else 0)
    u_lobe, _ = uniforms(seed)
    s = bsdf.sample(si, u_lobe, None)
    for wi in (upper_directions(si, seed), s.wi):
        f_cos, pdf = bsdf.eval(si, wi)
        if np.any(f_cos != 0.0) or np.any(pdf != 0.0) or np.any(bsdf.pdf(si, wi) != 0.0):
            return False
    return bool(np.all((s.flags & BSDFFlags.DELTA) != 0))


def make(cls, fresnel="exact"):
    return cls(MATERIALS, RenderSettings(fresnel=fresnel))


# -- every implementation --------------------------------------------------------------------------
def test_the_table_has_one_bsdf_per_material_kind_in_scatter_group_order():
    table = MaterialTable(MATERIALS, RenderSettings())
    assert [type(b) for b in table.bsdfs] == [cls for _, cls in SCATTERING]
    assert [cls for _, cls in SCATTERING][:6] == [Lambertian, PerfectMirror, SmoothGlass, MicrofacetReflection,
                                                  PrincipledV2, RoughDiffuse]     # later rows: tests of their BSDFs
    assert list(table.scatter_group) == [0, 1, 2] and table.non_delta[:6] == [True, False, False, True, True, True]
    assert {DIFFUSE, GLOSSY, PRINCIPLED, ROUGH_DIFFUSE} <= NON_DELTA_KINDS   # the rows whose hits take shadow rays
    assert not NON_DELTA_KINDS & {MIRROR, GLASS}
    rough = MaterialTable([Material("Clay", DIFFUSE, diffuse_roughness=0.5), Material("Wall", DIFFUSE)], RenderSettings())
    assert list(rough.scatter_group) == [KIND_CODE[ROUGH_DIFFUSE], 0]          # roughness 0 stays Lambertian
    black = MaterialTable([Material("Black", DIFFUSE, (0, 0, 0))], RenderSettings())
    assert list(black.scatter_group) == [len(SCATTERING)]                          # ABSORB
    textured = MaterialTable([Material("Black", DIFFUSE, (0, 0, 0))], RenderSettings(), np.array([True]))
    assert list(textured.scatter_group) == [0]


@pytest.mark.parametrize("seed", [1, 2])
def test_lambertian_sample_is_eval_over_pdf(seed):
    si = hits(seed)
    assert sample_matches_eval(Lambertian(MATERIALS, RenderSettings()), si, seed)


def test_lambertian_sample_value_is_the_colour_exactly():
    """f cos / pdf = rho, bit for bit (eq. 2.14): the image does not depend on a division."""
    si = hits(3)
    u_lobe, u = uniforms(3)
    s = Lambertian(MATERIALS, RenderSettings()).sample(si, u_lobe, u)
    assert np.array_equal(s.value, si.color)
    assert np.all(s.flags == BSDFFlags.DIFFUSE | BSDFFlags.REFLECTION)
    assert np.all((s.wi * si.n).sum(axis=0) > 0.0)


def test_lambertian_is_reciprocal_and_conserves_energy():
    bsdf = Lambertian(MATERIALS, RenderSettings())
    assert reciprocal(bsdf, 4)
    assert conserves_energy(bsdf, 5)


def test_lambertian_is_zero_below_the_shading_normal():
    si = hits(6)
    below = -upper_directions(si, 6)
    bsdf = Lambertian(MATERIALS, RenderSettings())
    f_cos, pdf = bsdf.eval(si, below)
    assert np.all(f_cos == 0.0) and np.all(pdf == 0.0)
    assert np.array_equal(bsdf.lambert_albedo(si), si.color)


@pytest.mark.parametrize("cls", [PerfectMirror, SmoothGlass])
def test_delta_lobes_have_no_density_and_conserve_energy(cls):
    bsdf = make(cls)
    assert not has_non_delta(bsdf.flags) and bsdf.lambert_albedo(hits(7)) is None
    assert delta_has_no_density(bsdf, 7)
    assert conserves_energy(bsdf, 8)


def test_mirror_reflects_about_the_normal():
    si = hits(9, color=(0.9, 0.9, 0.9), material=1)
    s = make(PerfectMirror).sample(si, uniforms(9)[0], None)
    cos_o, cos_i = (si.wo * si.n).sum(axis=0), (s.wi * si.n).sum(axis=0)
    assert np.allclose(cos_i, cos_o, atol=1e-12)
    assert np.allclose(s.wi + si.wo, 2.0 * cos_o * si.n, atol=1e-12)            # eq. 2.20
    assert np.array_equal(s.value, si.color) and np.all(s.pdf == 1.0)
    assert np.all(s.flags == BSDFFlags.DELTA | BSDFFlags.REFLECTION)


@pytest.mark.parametrize("fresnel", ["schlick", "exact"])
def test_glass_chooses_reflection_with_the_fresnel_probability(fresnel):
    """From outside at 60 degrees: the reflected fraction of samples is R (a 4-sigma binomial
    interval), the pdf of each sample is R or T, reflections mirror and refractions obey Snell."""
    from engine.materials.fresnel import FRESNEL
    from engine.materials.specular import refract_cos
    n = 100_000
    theta = np.radians(60.0)
    nrm = np.tile([[0.0], [0.0], [1.0]], (1, n))
    wo = np.tile([[np.sin(theta)], [0.0], [np.cos(theta)]], (1, n))
    si = ShadingPoint(wo, nrm, nrm, nrm, np.ones((3, n)), np.full(n, GLASS_ID, dtype=np.int64))
    s = make(SmoothGlass, fresnel).sample(si, np.random.default_rng(10).random(n), None)
    cos_t, tir = refract_cos(np.array([np.cos(theta)]), np.array([1 / 1.5]))
    r = FRESNEL[fresnel](np.array([np.cos(theta)]), cos_t, np.array([1 / 1.5]), tir)[0]
    reflected = (s.flags & BSDFFlags.REFLECTION) != 0
    assert np.all(reflected | ((s.flags & BSDFFlags.TRANSMISSION) != 0))
    assert abs(reflected.mean() - r) < 4.0 * np.sqrt(r * (1 - r) / n)
    assert np.allclose(s.pdf, np.where(reflected, r, 1.0 - r))
    assert np.allclose(s.wi[2, reflected], np.cos(theta)) and np.all(s.wi[2, ~reflected] < 0.0)
    sin_t = np.hypot(s.wi[0, ~reflected], s.wi[1, ~reflected])
    assert np.allclose(1.5 * sin_t, np.sin(theta), atol=1e-12)                  # Snell, eq. 2.21
    assert np.array_equal(s.value, si.color)


def test_glass_reflects_totally_beyond_the_critical_angle():
    """Inside the glass (outward normal against the viewer) at 60 degrees > 41.8: R = 1."""
    n = 1000
    theta = np.radians(60.0)
    facing = np.tile([[0.0], [0.0], [1.0]], (1, n))
    wo = np.tile([[np.sin(theta)], [0.0], [np.cos(theta)]], (1, n))
    si = ShadingPoint(wo, facing, facing, -facing, np.ones((3, n)), np.full(n, GLASS_ID, dtype=np.int64))
    s = make(SmoothGlass).sample(si, np.random.default_rng(11).random(n), None)
    assert np.all(s.flags == BSDFFlags.DELTA | BSDFFlags.REFLECTION) and np.all(s.pdf == 1.0)


def test_specular_lobes_bend_a_smooth_normal_so_the_reflection_clears_the_surface():
    """Shading normal tilted 40 degrees, viewer grazing: the plain mirror direction would go
    below the geometric surface; with si.smooth the BSDF reflects about Cycles' bent normal."""
    ng = np.array([[0.0], [0.0], [1.0]])
    tilt = np.radians(40.0)
    ns = np.array([[np.sin(tilt)], [0.0], [np.cos(tilt)]])
    wo = unit(np.array([[-1.0], [0.0], [0.05]]))
    for smooth, clears in ((False, False), (True, True)):
        si = ShadingPoint(wo, ns, ng, ng, np.ones((3, 1)), np.zeros(1, dtype=np.int64), smooth=smooth)
        wi = make(PerfectMirror).sample(si, np.zeros(1), None).wi
        assert (wi[2, 0] > 0.0) == clears, (smooth, wi[:, 0])


# -- controls: each check fails a broken BSDF -----------------------------------------------------
class TwiceTheAlbedo(Lambertian):
    """value = 2 rho: gains energy, and is no longer eval / pdf."""
    def sample(self, si, u_lobe, u):
        s = super().sample(si, u_lobe, u)
        s.value = 2.0 * s.value
        return s


class Anisotropic(Lambertian):
    """f depends on the angle to the viewer only: not reciprocal."""
    def eval(self, si, wi):
        f_cos, pdf = super().eval(si, wi)
        return f_cos * (0.5 + (si.wo * si.n).sum(axis=0)), pdf


class LeakyMirror(PerfectMirror):
    """A delta lobe that claims a density."""
    def pdf(self, si, wi):
        return np.ones(wi.shape[1])


def test_the_checks_fail_broken_bsdfs():
    broken = TwiceTheAlbedo(MATERIALS, RenderSettings())
    assert not sample_matches_eval(broken, hits(12), 12)
    assert not conserves_energy(broken, 12)
    assert not reciprocal(Anisotropic(MATERIALS, RenderSettings()), 13)
    assert not delta_has_no_density(make(LeakyMirror), 14)


def test_the_table_knows_glossy_rays_from_the_rows_flags():
    """lamps_seen counts a round lamp on a glossy or transmission ray only after a delta bounce when
    some BSDF sends such rays (engine/integrators/path_tracer.py): every row that does must say so,
    Blender 3.x's Principled BSDF too (a hand-kept list of rows once left it out)."""
    from engine.scene.model import PrincipledV1, TRANSLUCENT
    def glossy(*materials):
        return MaterialTable(list(materials), RenderSettings()).glossy
    assert glossy(Material("v1", PRINCIPLED, principled=PrincipledV1()))
    assert glossy(Material("v2", PRINCIPLED)) and glossy(Material("g", GLOSSY, roughness=0.3))
    assert glossy(Material("frosted", GLASS, roughness=0.3)) and glossy(Material("sheet", TRANSLUCENT))
    assert not glossy(Material("wall", DIFFUSE), Material("clay", DIFFUSE, diffuse_roughness=0.5),
                      Material("mirror", MIRROR), Material("glass", GLASS))
