"""Rough dielectrics, refraction, transparent and translucent BSDFs (engine/materials/dielectric.py,
glass_albedo.py, transparent.py, translucent.py) and how the scene model and table choose them.

The samplers are χ²-tested against their own pdf over the whole sphere (reflection and
transmission hemispheres at once), from outside (eta = 1.5) and inside (eta = 1 / 1.5), near
normal and grazing; sampled pdf = pdf(), value = eval / pdf; the reciprocity of the BSDF without
radiance scaling, f(wo, wi) n_wo^2 = f(wi, wo) n_wi^2; the white furnace (reflection + transmission
<= 1, the loss 1 - E, and the compensated lobe).  Controls: a pdf of the wrong roughness fails the
χ², a BSDF with the 1 / eta^2 radiance factor fails reciprocity."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.materials import glass_albedo
from engine.materials.dielectric import RoughGlass, RoughRefraction, SmoothRefraction
from engine.materials.dielectric_lobe import MicrofacetDielectric, dielectric_alpha
from engine.materials.media import MediumStack
from engine.materials.protocol import BSDFFlags, ShadingPoint
from engine.materials.table import ROUGH_GLASS, ROUGH_REFRACTION, MaterialTable, scatter_kind
from engine.materials.translucent import Translucent
from engine.materials.transparent import Transparent
from engine.scene.model import GLASS, REFRACTION, TRANSLUCENT, Material
from tests.chi_square import ALPHA, sphere_chi2

SETTINGS = RenderSettings()
IOR = 1.5


def glass(roughness, distribution="ggx", kind=GLASS, color=(1.0, 1.0, 1.0)):
    return [Material("G", kind, color, ior=IOR, roughness=roughness, distribution=distribution)]


def fixed_hits(n, mu, inside=False, color=(1.0, 1.0, 1.0)):
    """n hits at a surface with normal +z, wo at cos = mu in the xz plane; inside: the viewer is in the glass
    (the outward normal points away from it)."""
    z = np.tile([[0.0], [0.0], [1.0]], (1, n))
    wo = np.tile([[np.sqrt(1.0 - mu * mu)], [0.0], [mu]], (1, n))
    return ShadingPoint(wo, z, z, -z if inside else z, np.tile(np.asarray(color, float)[:, None], (1, n)),
                        np.zeros(n, dtype=np.int64))


def random_hits(seed, n=3000, inside=None):
    rng = np.random.default_rng(seed)
    nrm = rng.normal(size=(3, n))
    nrm /= np.linalg.norm(nrm, axis=0)
    wo = rng.normal(size=(3, n))
    wo /= np.linalg.norm(wo, axis=0)
    wo *= np.where((wo * nrm).sum(axis=0) < 0.0, -1.0, 1.0)
    side = np.where(rng.random(n) < 0.5, -1.0, 1.0) if inside is None else (-1.0 if inside else 1.0)
    return ShadingPoint(wo, nrm, nrm, nrm * side, np.tile([[0.9], [0.7], [0.5]], (1, n)), np.zeros(n, dtype=np.int64))


def sampler_and_pdf(bsdf, mu, inside, seed=0, pdf_bsdf=None):
    def sample(u):
        n = u.shape[1]
        s = bsdf.sample(fixed_hits(n, mu, inside), np.random.default_rng(seed + 7).random(n), (u[0], u[1]))
        return np.where(s.value.max(axis=0) > 0.0, s.wi, 0.0)

    def pdf(d):
        return (pdf_bsdf or bsdf).pdf(fixed_hits(d.shape[1], mu, inside), d)
    return sample, pdf


FAST = [("ggx", 0.25, 0.95, False), ("ggx", 1.0, 0.2, True), ("beckmann", 0.25, 0.2, False)]
CASES = [pytest.param(*case, marks=[] if case in FAST else [pytest.mark.slow])
         for case in [("ggx", r, mu, inside) for r in (0.25, 1.0) for mu in (0.95, 0.2) for inside in (False, True)]
         + [("beckmann", 0.25, 0.2, False), ("beckmann", 0.6, 0.95, True), ("beckmann", 1.0, 0.2, True),
            ("ggx", 0.1, 0.7, False), ("ggx", 0.1, 0.3, True)]]


def refine_for(roughness):
    """Midpoint sub-cells per cell side: sharp lobes need more (the transmitted lobe is narrower)."""
    return 24 if roughness > 0.2 else 40


@pytest.mark.parametrize("dist, roughness, mu, inside", CASES)
def test_rough_glass_sampler_chi2(dist, roughness, mu, inside):
    bsdf = RoughGlass(glass(roughness, dist), SETTINGS)
    p, _ = sphere_chi2(*sampler_and_pdf(bsdf, mu, inside), n=100_000, refine=refine_for(roughness))
    assert p > ALPHA


@pytest.mark.parametrize("roughness, mu, inside", [(0.25, 0.8, False), pytest.param(0.6, 0.3, True, marks=pytest.mark.slow)])
def test_rough_refraction_sampler_chi2(roughness, mu, inside):
    bsdf = RoughRefraction(glass(roughness, kind=REFRACTION), SETTINGS)
    p, _ = sphere_chi2(*sampler_and_pdf(bsdf, mu, inside), n=100_000, refine=refine_for(roughness))
    assert p > ALPHA


def test_chi2_control_a_pdf_of_another_roughness_fails():
    bsdf = RoughGlass(glass(0.25), SETTINGS)
    wrong = RoughGlass(glass(0.3), SETTINGS)
    p, _ = sphere_chi2(*sampler_and_pdf(bsdf, 0.95, False, pdf_bsdf=wrong), n=100_000, refine=16)
    assert p < 1e-6


@pytest.mark.parametrize("cls, roughness", [(RoughGlass, 0.02), (RoughGlass, 0.25), (RoughGlass, 1.0),
                                            (RoughRefraction, 0.25)])
@pytest.mark.parametrize("distribution", ["ggx", "beckmann", "multi_ggx"])
def test_sampled_pdf_and_weight_match_eval(cls, roughness, distribution):
    bsdf = cls(glass(roughness, distribution, kind=GLASS if cls is RoughGlass else REFRACTION), SETTINGS)
    si = random_hits(11)
    rng = np.random.default_rng(12)
    s = bsdf.sample(si, rng.random(len(si)), (rng.random(len(si)), rng.random(len(si))))
    valid = np.flatnonzero(s.value.max(axis=0) > 0.0)
    assert len(valid) > 0.5 * len(si)
    at, wi = si.take(valid), s.wi.take(valid, axis=1)
    f_cos, pdf = bsdf.eval(at, wi)
    assert np.allclose(s.pdf.take(valid), pdf, rtol=1e-7)
    assert np.allclose(s.value.take(valid, axis=1), f_cos / pdf, rtol=1e-7)
    through = (s.flags.take(valid) & BSDFFlags.TRANSMISSION) != 0
    assert np.all(((wi * at.ng).sum(axis=0) < 0.0) == through)          # each lobe on its side
    if cls is RoughGlass:
        assert 0.0 < through.mean() < 1.0


def swapped(si, wi):
    """The hits seen from wi: the viewer-side normals flip where wi is beyond the surface."""
    flip = np.where((wi * si.n).sum(axis=0) < 0.0, -1.0, 1.0)
    return ShadingPoint(wi, si.n * flip, si.ng * flip, si.normal, si.color, si.material)


def reciprocity_error(bsdf, seed, radiance_scaled=False):
    """max relative |f(wo, wi) n_wo^2 - f(wi, wo) n_wi^2| over random pairs (both hemispheres)."""
    si = random_hits(seed)
    rng = np.random.default_rng(seed + 1)
    wi = rng.normal(size=(3, len(si)))
    wi /= np.linalg.norm(wi, axis=0)
    f_ab = bsdf.eval(si, wi)[0][0] / np.abs((wi * si.n).sum(axis=0))
    f_ba = bsdf.eval(swapped(si, wi), si.wo)[0][0] / np.abs((si.wo * si.n).sum(axis=0))
    outside_o = (si.wo * si.normal).sum(axis=0) > 0.0
    outside_i = (wi * si.normal).sum(axis=0) > 0.0
    n_o, n_i = np.where(outside_o, 1.0, IOR), np.where(outside_i, 1.0, IOR)
    if radiance_scaled:                                     # pbrt's radiance BTDF: f / eta^2
        f_ab, f_ba = f_ab * (n_o / n_i) ** 2, f_ba * (n_i / n_o) ** 2
    a, b = f_ab * n_o ** 2, f_ba * n_i ** 2
    both = (a > 1e-6) | (b > 1e-6)
    assert both.sum() > 500 and ((outside_o != outside_i) & both).sum() > 100
    return float(np.max(np.abs(a - b)[both] / np.maximum(a, b)[both]))


@pytest.mark.parametrize("roughness", [0.25, 1.0])
def test_rough_glass_reciprocity_with_eta_squared(roughness):
    assert reciprocity_error(RoughGlass(glass(roughness), SETTINGS), 21) < 1e-9


def test_reciprocity_control_radiance_scaled_btdf_fails():
    assert reciprocity_error(RoughGlass(glass(0.25), SETTINGS), 21, radiance_scaled=True) > 0.5


def furnace(distribution, roughness, mu, inside, n=200_000, seed=3):
    """Mean throughput weight (reflection, transmission) of a white rough glass seen at cos = mu."""
    bsdf = RoughGlass(glass(roughness, distribution), SETTINGS)
    rng = np.random.default_rng(seed)
    s = bsdf.sample(fixed_hits(n, mu, inside), rng.random(n), (rng.random(n), rng.random(n)))
    through = (s.flags & BSDFFlags.TRANSMISSION) != 0
    return s.value[0][~through].sum() / n, s.value[0][through].sum() / n


@pytest.mark.parametrize("roughness, mu, inside", [(0.5, 0.5, False), (1.0, 0.5, False), (1.0, 0.9, True),
                                                   (0.5, 0.2, True)])
def test_white_furnace_single_scatter_loses_and_matches_its_table(roughness, mu, inside):
    r, t = furnace("ggx", roughness, mu, inside)
    eta = 1.0 / IOR if inside else IOR
    assert r + t <= 1.0
    strict = glass_albedo.estimate_albedo(roughness, mu, eta, 256, seed=9, refraction_side=True)
    assert abs((r + t) - strict) < 0.005
    table = glass_albedo.estimate_albedo(roughness, mu, eta, 256, seed=9)     # as Cycles' tables: no side check
    assert abs(glass_albedo.albedo(roughness, mu, eta) - table) < 0.01        # interpolated between grid points
    assert table >= strict


def test_white_furnace_compensated_entering_reads_one():
    for roughness, mu in ((0.5, 0.5), (1.0, 0.5), (1.0, 0.9)):
        r, t = furnace("multi_ggx", roughness, mu, False)
        assert abs(r + t - 1.0) < 0.006, (roughness, mu, r + t)
        r1, t1 = furnace("ggx", roughness, mu, False)
        assert r1 + t1 < r + t


def test_glass_tables_against_the_estimator():
    """Spot checks of ggx_glass_albedo.npz against fresh estimates (other seeds) at grid points."""
    for k, j, i in ((3, 8, 7), (8, 15, 15), (12, 4, 10)):
        eta = float(glass_albedo.eta_of_z(k / 15))
        for e, key in ((eta, "E"), (1.0 / eta, "E_inv")):
            fresh = glass_albedo.estimate_albedo(i / 15, j / 15, e, 128, seed=77)
            assert abs(glass_albedo.tables()[key][k, j, i] - fresh) < 0.005


def test_rough_glass_keeps_the_medium_stack():
    mats = glass(0.3)
    bsdf = RoughGlass(mats, SETTINGS)
    n = 2000
    si = fixed_hits(n, 0.9)
    si.media = MediumStack.empty(n)
    rng = np.random.default_rng(5)
    s = bsdf.sample(si, rng.random(n), (rng.random(n), rng.random(n)))
    through = (s.flags & BSDFFlags.TRANSMISSION) != 0
    assert through.mean() > 0.8
    assert np.all(si.media.depth[through] == 1) and np.all(si.media.media[through, 0] == IOR)
    assert np.all(si.media.depth[~through] == 0)


def test_smooth_refraction_has_no_reflection_and_tir_ends():
    bsdf = SmoothRefraction(glass(0.0, kind=REFRACTION), SETTINGS)
    s = bsdf.sample(fixed_hits(4, 0.8, inside=False, color=(0.5, 0.6, 0.7)), np.zeros(4))
    assert np.all(s.wi[2] < 0) and np.allclose(s.value[:, 0], (0.5, 0.6, 0.7))
    assert np.allclose(-s.wi[0, 0], np.sqrt(1 - 0.64) / IOR)                      # Snell
    s = bsdf.sample(fixed_hits(4, 0.3, inside=True), np.zeros(4))                 # beyond the critical angle
    assert np.all(s.value == 0.0)


def test_transparent_passes_exactly():
    si = random_hits(31)
    s = Transparent([], SETTINGS).sample(si, np.zeros(len(si)))
    assert np.array_equal(s.wi, -si.wo) and np.array_equal(s.value, si.color)
    assert s.flags[0] == BSDFFlags.DELTA | BSDFFlags.TRANSMISSION | BSDFFlags.STRAIGHT   # a camera ray goes on as one


def test_translucent_sampler_chi2_and_eval():
    bsdf = Translucent([], SETTINGS)

    def sample(u):
        return bsdf.sample(fixed_hits(u.shape[1], 0.6), None, (u[0], u[1])).wi

    p, _ = sphere_chi2(sample, lambda d: bsdf.pdf(fixed_hits(d.shape[1], 0.6), d), n=100_000)
    assert p > ALPHA
    wrong = sphere_chi2(sample, lambda d: np.maximum(-d[2], 0.0) ** 1.2 * (2.2 / (2 * np.pi)), n=100_000)[0]
    assert wrong < 1e-6                                            # control: another lobe
    si = random_hits(41)
    s = bsdf.sample(si, None, tuple(np.random.default_rng(1).random((2, len(si)))))
    assert np.all((s.wi * si.n).sum(axis=0) <= 0.0)
    f_cos, pdf = bsdf.eval(si, s.wi)
    assert np.allclose(s.value, f_cos / pdf)


def test_roughness_default_keeps_glass_smooth():
    assert Material("g", GLASS).roughness == 0.0 and scatter_kind(Material("g", GLASS)) == GLASS
    assert Material("r", REFRACTION).roughness == 0.0
    assert Material("d").roughness == 0.5 and Material("t", TRANSLUCENT).roughness == 0.5
    assert scatter_kind(Material("g", GLASS, roughness=0.2)) == ROUGH_GLASS
    assert scatter_kind(Material("g", REFRACTION, roughness=0.2)) == ROUGH_REFRACTION
    table = MaterialTable([Material("g", GLASS), Material("h", GLASS, roughness=0.4)], SETTINGS)
    assert table.kind[0] != table.kind[1] and table.glossy


def test_scene_files_keep_glass_smooth_and_rough(tmp_path):
    from engine.scene.builtin import cornell_scene
    from engine.scene.files import load_scene, save_scene
    scene = cornell_scene((8, 8))
    scene.materials.append(Material("Frosted", GLASS, roughness=0.3, distribution="beckmann"))
    path = tmp_path / "s.json"
    save_scene(scene, str(path))
    text = path.read_text()
    assert text.count('"roughness"') == 1                          # only the rough glass writes one
    loaded = load_scene(str(path))
    by_name = {m.name: m for m in loaded.materials}
    assert by_name["Frosted"].roughness == 0.3 and by_name["Frosted"].distribution == "beckmann"
    assert all(m.roughness == 0.0 for m in loaded.materials if m.kind == GLASS and m.name != "Frosted")


def test_bad_dielectric_input_names_the_material():
    from engine.core.errors import SceneError
    with pytest.raises(SceneError, match="'G'.*roughness"):
        Material("G", GLASS, roughness=1.5).validate()
    with pytest.raises(SceneError, match="'G'.*distribution"):
        Material("G", GLASS, roughness=0.5, distribution="ashikhmin").validate()


def test_lobe_alpha_is_roughness_squared():
    assert dielectric_alpha(0.5) == 0.25 and dielectric_alpha(0.0) > 0.0
    lobe = MicrofacetDielectric(reflection=False)
    r, t = lobe.split(np.array([1.0, 0.1]), np.array([1.5, 1 / 1.5]))
    assert np.array_equal(r, [0.0, 0.0]) and np.array_equal(t, [1.0, 0.0])     # TIR at the second


def test_blender34_glass_uses_separable_masking():
    """Cycles before 3.5: G1(wo) G1(wi) <= G2: darker single-scatter glass; sample and eval still agree; the
    compensated (multi_ggx) glass keeps the height-correlated lobe its tables were made for."""
    old, new = RoughGlass(glass(0.8), SETTINGS, (3, 4)), RoughGlass(glass(0.8), SETTINGS, (5, 0))
    si = fixed_hits(50_000, 0.5)
    rng = np.random.default_rng(8)
    u = (rng.random(len(si)), (rng.random(len(si)), rng.random(len(si))))
    s_old, s_new = old.sample(si, *u), new.sample(si, *u)
    assert s_old.value[0].mean() < s_new.value[0].mean() - 0.005
    valid = np.flatnonzero(s_old.value[0] > 0)
    f_cos, pdf = old.eval(si.take(valid), s_old.wi.take(valid, axis=1))
    assert np.allclose(s_old.value.take(valid, axis=1), f_cos / pdf, rtol=1e-7)
    assert not RoughGlass(glass(0.8, "multi_ggx"), SETTINGS, (3, 4)).separable.any()



def cap_chi2(bsdf, mu, inside, axis, theta_max, n=100_000, seed=0, bins=(16, 32), refine=8, pdf_bsdf=None):
    """χ² p-value of a near-delta lobe in a cap of half-angle theta_max about `axis` (bins (theta, phi)
    cells, theta linear) plus one cell for the valid samples outside the cap."""
    from engine.sampling.warps import orthonormal_basis
    from tests.chi_square import pooled_chi2
    axis = np.asarray(axis, float).reshape(3, 1) / np.linalg.norm(axis)
    t1, t2 = (v[:, 0] for v in orthonormal_basis(axis))
    sample, pdf = sampler_and_pdf(bsdf, mu, inside, seed, pdf_bsdf)
    d = sample(np.random.default_rng(seed).random((2, n)))
    d = d[:, np.abs(d).sum(axis=0) > 0]
    theta = np.arccos(np.clip((d * axis).sum(axis=0), -1.0, 1.0))
    phi = np.mod(np.arctan2(d.T @ t2, d.T @ t1), 2 * np.pi)
    nt, nphi = bins
    cap = theta < theta_max
    cell = (np.minimum((theta[cap] / theta_max * nt).astype(int), nt - 1) * nphi
            + np.minimum((phi[cap] / (2 * np.pi) * nphi).astype(int), nphi - 1))
    observed = np.append(np.bincount(cell, minlength=nt * nphi), (~cap).sum())
    kt, kp = nt * refine, nphi * refine
    tt, pp = np.meshgrid((np.arange(kt) + 0.5) * theta_max / kt, (np.arange(kp) + 0.5) * 2 * np.pi / kp,
                         indexing="ij")
    dirs = (np.cos(tt)[None] * axis[:, :, None] + (np.sin(tt) * np.cos(pp))[None] * t1[:, None, None]
            + (np.sin(tt) * np.sin(pp))[None] * t2[:, None, None]).reshape(3, -1)
    mass = pdf(dirs).reshape(kt, kp) * np.sin(tt) * (theta_max / kt) * (2 * np.pi / kp)
    expected = n * mass.reshape(nt, refine, nphi, refine).sum(axis=(1, 3)).ravel()
    return pooled_chi2(observed, np.append(expected, max(d.shape[1] - expected.sum(), 0.0)))[0]


@pytest.mark.parametrize("inside", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_near_delta_glass_chi2_in_caps_about_the_specular_directions(inside):
    """Roughness 0.02 (alpha 4e-4): the sphere grid cannot resolve it, so each lobe is tested in a cap of
    0.008 rad about its mirror / refracted direction, 32 midpoint sub-cells per cell side (8 integrate
    the refracted lobe too coarsely: p = 10^-4 for a right sampler).  Control: the pdf of roughness
    0.025 fails."""
    mu, eta = 0.9, (1.0 / IOR if inside else IOR)
    s = np.sqrt(1 - mu * mu)
    sin_t = s / eta
    reflected, refracted = (-s, 0.0, mu), (-sin_t, 0.0, -np.sqrt(1 - sin_t * sin_t))
    bsdf = RoughGlass(glass(0.02), SETTINGS)
    for axis in (reflected, refracted):
        assert cap_chi2(bsdf, mu, inside, axis, 0.008, seed=1, refine=32) > ALPHA
    assert cap_chi2(bsdf, mu, inside, refracted, 0.008, seed=1, pdf_bsdf=RoughGlass(glass(0.025), SETTINGS)) < 1e-6
