"""Filter Glossy on mirrors and smooth glass (engine/integrators/delta_blur.py): which hits move to
the blurred rows, what the blurred lobes give against a GGX lobe of the floor's alpha (a quadrature
of its eval), their energy, and what stays as it was (Filter Glossy 0, Sharp closures, photons)."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from engine.core.settings import RenderSettings
from engine.geometry.scene_geometry import TRIANGLE, HitSet
from engine.integrators.delta_blur import DeltaBlur, regroup
from engine.integrators.effects import plan_effects
from engine.materials.protocol import BSDFFlags, ShadingPoint, has_non_delta
from engine.materials.table import (ABSORB, BLURRED_MIRROR, KIND_CODE, N_SCATTER_GROUPS, ROUGH_GLASS,
                                    ROUGH_REFRACTION, MaterialTable)
from engine.scene.model import DIFFUSE, GLASS, GLOSSY, MIRROR, REFRACTION, Material

from .test_light_paths import image, scene_of

ALPHA = 0.3                 # the floor the tests blur with
N = 40_000                  # BSDF samples per estimate


def table():
    """diffuse 0, mirror 1, glass 2, refraction 3, a 3.x Sharp mirror 4, a black mirror 5, the GGX
    references of alpha ALPHA: glossy 6 and glass 7 (roughness sqrt(ALPHA))."""
    r = np.sqrt(ALPHA)
    mats = [Material("d", DIFFUSE), Material("m", MIRROR, (0.9, 0.7, 0.5)), Material("g", GLASS, (1, 1, 1), ior=1.5),
            Material("r", REFRACTION, (1, 1, 1), ior=1.5), Material("s", MIRROR, (0.9, 0.7, 0.5), sharp_closure=True),
            Material("k", MIRROR, (0, 0, 0)),
            Material("G", GLOSSY, (0.9, 0.7, 0.5), roughness=r, multiscatter=False),
            Material("R", GLASS, (1, 1, 1), ior=1.5, roughness=r)]
    return MaterialTable(mats, RenderSettings())


def hits_of(material, group_of):
    """A HitSet of triangle hits on `material` (one per ray, rays 0..n-1), sorted by group."""
    n = len(material)
    flat = HitSet(np.arange(n), np.zeros(0, np.int64), np.ones(n), np.full(n, TRIANGLE, np.int8), np.arange(n),
                  np.zeros(n), np.zeros(n), np.asarray(material), {}, [])
    return regroup(flat, group_of.take(material), N_SCATTER_GROUPS)


def test_regroup_moves_the_blurrable_delta_hits_of_paths_with_a_floor():
    mats = table()
    material = np.array([0, 1, 2, 3, 4, 5, 1, 2, 3, 0])
    min_pdf = np.array([0.3, 0.3, 0.3, 0.3, 0.3, 0.3, np.inf, np.inf, np.inf, np.inf])   # by ray
    hits = hits_of(material, mats.scatter_group)
    blur = DeltaBlur(mats.scatter_group, mats.blurred_group, 1.0, N_SCATTER_GROUPS)
    moved = blur.regroup(hits, min_pdf)
    group = {int(ray): g for g, (a, b) in enumerate(moved.groups) for ray in moved.index[a:b]}
    assert group == {0: KIND_CODE[DIFFUSE], 1: KIND_CODE[BLURRED_MIRROR], 2: KIND_CODE[ROUGH_GLASS],
                     3: KIND_CODE[ROUGH_REFRACTION], 4: KIND_CODE[MIRROR], 5: ABSORB,
                     6: KIND_CODE[MIRROR], 7: KIND_CODE[GLASS], 8: KIND_CODE[REFRACTION], 9: KIND_CODE[DIFFUSE]}
    for (g, k), (a, b) in moved.runs.items():        # runs and arrays follow the new order
        assert k == TRIANGLE and moved.groups[g] == (a, b)
        np.testing.assert_array_equal(moved.prim[a:b], moved.index[a:b])
        np.testing.assert_array_equal(moved.material[a:b], material.take(moved.index[a:b]))
    # control: no floor (min_pdf >= the filter, or camera paths): the same HitSet object
    assert blur.regroup(hits, np.full(10, np.inf)) is hits
    assert blur.regroup(hits, np.full(10, 1.0)) is hits
    # a ray forced to absorb (the depth limit) stays there
    forced = regroup(hits, np.where(hits.index == 1, ABSORB, mats.scatter_group.take(hits.material)), N_SCATTER_GROUPS)
    out = blur.regroup(forced, min_pdf)
    assert 1 in out.index[slice(*out.groups[ABSORB])]


def shading(n, wo, material, floor):
    z = np.tile([[0.0], [0.0], [1.0]], n)
    return ShadingPoint(np.tile(wo[:, None], n), z, z, z, np.ones((3, n)), np.full(n, material, np.int64),
                        alpha_floor=None if floor is None else np.full(n, floor))


def sampled_mean(bsdf, si, g, rng):
    """mean and standard error (3,) of value x g(wi) over BSDF samples."""
    u = rng.random((3, len(si)))
    s = bsdf.sample(si, u[0], (u[1], u[2]))
    x = s.value * g(s.wi)
    return x.mean(axis=1), x.std(axis=1) / np.sqrt(len(si))


def quadrature(bsdf, si_of, g, sphere=False, n_mu=200, n_phi=300):
    """The integral of eval's f cos x g over the hemisphere above z (or the sphere): midpoints in
    (cos theta, phi)."""
    lo = -1.0 if sphere else 0.0
    mu = lo + (np.arange(n_mu) + 0.5) * (1.0 - lo) / n_mu
    phi = (np.arange(n_phi) + 0.5) * 2.0 * np.pi / n_phi
    mu, phi = np.meshgrid(mu, phi, indexing="ij")
    mu, phi = mu.ravel(), phi.ravel()
    s = np.sqrt(np.maximum(0.0, 1.0 - mu * mu))
    wi = np.stack([s * np.cos(phi), s * np.sin(phi), mu])
    f, _ = bsdf.eval(si_of(len(mu)), wi)
    return (f * g(wi)).sum(axis=1) * (1.0 - lo) / n_mu * 2.0 * np.pi / n_phi


WO = np.array([np.sin(0.7), 0.0, np.cos(0.7)])             # 40 degrees off the normal
LOBE_AT = np.array([-np.sin(0.95), 0.0, np.cos(0.95)])      # 14 degrees past the mirror direction


def lobe(wi):
    return np.exp(6.0 * (wi * LOBE_AT[:, None]).sum(axis=0) - 6.0)


def test_a_blurred_mirror_is_the_ggx_lobe_of_the_floors_alpha():
    """The mirror's blurred row, sampled at floor ALPHA, gives the integral of a Glossy GGX of alpha
    ALPHA (no Fresnel, the same colour) against a lobe beside the mirror direction, within 4 standard
    errors; the sharp mirror (control) does not.  Energy (g = 1): the GGX albedo, below the colour."""
    mats, rng = table(), np.random.default_rng(3)
    blurred = mats.bsdfs[mats.blurred_group[1]]
    assert has_non_delta(blurred.flags) and not blurred.flags & BSDFFlags.DELTA
    color = np.array([0.9, 0.7, 0.5])[:, None]
    si = shading(N, WO, 1, ALPHA)
    si.color = np.tile(color, N)
    ref_bsdf = mats.bsdfs[mats.scatter_group[6]]

    def ref_si(n):
        s = shading(n, WO, 6, None)
        s.color = np.tile(color, n)
        return s
    for g in (lobe, lambda wi: np.ones(wi.shape[1])):
        mean, err = sampled_mean(blurred, si, g, rng)
        ref = quadrature(ref_bsdf, ref_si, g)
        assert (np.abs(mean - ref) < 4.0 * err + 1e-4 * ref).all(), (mean, ref, err)
        sharp, _ = sampled_mean(mats.bsdfs[mats.scatter_group[1]], shading(N, WO, 1, ALPHA), g, rng)
        sharp = sharp * color[:, 0]
        if g is lobe:
            assert (np.abs(sharp - ref) > 20.0 * err).all(), (sharp, ref)        # control: the delta lobe
        else:
            assert (mean < color[:, 0]).all() and (mean > 0.8 * color[:, 0]).all()   # no energy gained
            np.testing.assert_allclose(sharp, color[:, 0])


@pytest.mark.slow
def test_blurred_smooth_glass_is_cycles_ggx_glass_of_the_floors_alpha():
    """Smooth glass's blurred row at floor ALPHA against the Glass BSDF (GGX) of alpha ALPHA over the
    sphere (reflection and refraction, entering and leaving): within 4 standard errors; the sharp glass
    (control) is not.  Energy: the single-scatter GGX glass's (Cycles sets its compensation up from
    roughness 0), below 1 where the sharp glass keeps 1."""
    mats, rng = table(), np.random.default_rng(5)
    blurred = mats.bsdfs[mats.blurred_group[2]]
    assert has_non_delta(blurred.flags) and blurred.flags & BSDFFlags.TRANSMISSION
    ref_bsdf = mats.bsdfs[mats.scatter_group[7]]
    for outside in (True, False):
        wo = WO if outside else -WO

        def si_of(n, material, floor=None):
            s = shading(n, wo, material, floor)
            if not outside:                         # the viewer inside: shading normals face it
                s.n = s.ng = -s.n
            return s

        def g_lobe(wi):
            return np.exp(3.0 * (wi * np.array([0.3, 0.2, -0.9])[:, None]).sum(axis=0) - 3.0)
        for g in (g_lobe, lambda wi: np.ones(wi.shape[1])):
            mean, err = sampled_mean(blurred, si_of(N, 2, ALPHA), g, rng)
            ref = quadrature(ref_bsdf, lambda n: si_of(n, 7), g, sphere=True, n_mu=400, n_phi=100)
            assert (np.abs(mean - ref) < 4.0 * err + 2e-3 * ref).all(), (outside, mean, ref, err)
            sharp, _ = sampled_mean(mats.bsdfs[mats.scatter_group[2]], si_of(N, 2), g, rng)
            if g is g_lobe:
                assert (np.abs(sharp - ref) > 10.0 * err).all(), (sharp, ref)     # control
            else:
                assert (mean < 1.0).all() and (mean > 0.75).all(), mean
                np.testing.assert_allclose(sharp, 1.0)


# -- the path tracer --------------------------------------------------------------------------------
def test_filter_glossy_0_sharp_closures_and_photons_keep_the_delta_lobes():
    """No blur with Filter Glossy 0, with the Sharp closures of 3.x or with caustic photons (the plan
    says why); Filter Glossy 1 on the Cornell box's mirror and glass balls blurs them (control)."""
    from engine.integrators.light_paths import LightPaths
    scene = scene_of("cornell", 10)

    def blur(scene, **settings):
        settings = RenderSettings(**settings)
        plan = plan_effects(scene, settings)
        mats = MaterialTable(scene.materials, settings)
        return plan, DeltaBlur.of(mats, LightPaths(settings, plan, mats.bsdfs), N_SCATTER_GROUPS)
    assert blur(scene)[1] is None
    plan, on = blur(scene, filter_glossy=1.0)
    assert on is not None and "'Mirror', 'Glass' as GGX lobes" in plan.reason["filter_glossy"], plan.reason["filter_glossy"]
    plan, photons = blur(scene, filter_glossy=1.0, caustics_method="photons")
    assert photons is None and plan.enabled["photon_caustics"] and not plan.enabled["filter_glossy"]
    assert "photons' specular" in plan.reason["filter_glossy"]
    plan, sharp = blur(sharp_cornell(scene), filter_glossy=1.0)
    assert sharp is None and not plan.enabled["filter_glossy"] and "Sharp closures" in plan.reason["filter_glossy"]


def sharp_cornell(scene):
    sharp = copy.deepcopy(scene)
    for m in sharp.materials:
        m.sharp_closure = m.kind in (MIRROR, GLASS)
    return sharp


@pytest.mark.slow
def test_renders_without_blur_are_the_same_bits():
    """Filter Glossy 1 on Sharp closures renders the bits of Filter Glossy 0; on the Cornell box's
    mirror and glass it changes the image (control), with finite pixels."""
    scene = scene_of("cornell", 8)
    off = image(scene, samples=2, backend="numpy")
    np.testing.assert_array_equal(image(sharp_cornell(scene), samples=2, filter_glossy=1.0, backend="numpy"), off)
    blurred = image(copy.deepcopy(scene), samples=2, filter_glossy=1.0, backend="numpy")
    assert np.isfinite(blurred).all() and not np.array_equal(blurred, off)


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_blurred_renders_agree_on_both_backends(backend):
    """The blurred Cornell box: the NumPy and numba backends give the same bits."""
    scene = scene_of("cornell", 10)
    ref = image(scene, samples=4, filter_glossy=1.0, backend="numpy")
    np.testing.assert_array_equal(image(copy.deepcopy(scene), samples=4, filter_glossy=1.0, backend=backend), ref)
