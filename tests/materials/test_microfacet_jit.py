"""The compiled GGX lobe geometry (engine/materials/microfacet_jit.py) against the NumPy path of
engine/materials/glossy.py MicrofacetReflection: eval and sample bit for bit, over roughness 0.02
to 1, anisotropy, every Fresnel kind, compensation on and off, directions below the surface and
at grazing; the BSDF protocol's use_backend reaches the Principled BSDF's lobes."""
from types import SimpleNamespace

import numpy as np

from engine.core.settings import RenderSettings
from engine.materials.glossy import MicrofacetReflection
from engine.materials.protocol import ShadingPoint
from tests.backend_capture import require_compiled

TWIN = "engine.materials.microfacet_jit"        # imported by use_backend, not here: numba may be missing
NUMBA = {"glossy": "numba"}


def _materials():
    out = []
    for i, (r, a, fresnel) in enumerate([(0.02, 0.0, "none"), (0.25, 0.0, "dielectric"), (1.0, 0.0, "conductor"),
                                         (0.4, 0.7, "f82"), (0.6, -0.5, "interpolated"), (0.1, 0.3, "dielectric")]):
        out.append(SimpleNamespace(roughness=r, anisotropy=a, rotation=0.1 * i, tangent=(1.0, 0.0, 0.0),
                                   distribution="ggx", fresnel=fresnel, ior=1.45, multiscatter=i % 2 == 0,
                                   edge_tint=(0.9, 0.8, 0.7)))
    return out


def _hits(rng, m, count):
    n = rng.normal(size=(3, count))
    n /= np.linalg.norm(n, axis=0)
    wo = rng.normal(size=(3, count))
    wo /= np.linalg.norm(wo, axis=0)
    wo = np.where((wo * n).sum(axis=0) < 0.0, -wo, wo)
    wo[:, :50] = n[:, :50]                                          # normal incidence
    graze = np.cross(n[:, 50:100].T, rng.normal(size=(50, 3))).T    # in the tangent plane
    wo[:, 50:100] = graze / np.linalg.norm(graze, axis=0)
    color = rng.random((3, count))
    return ShadingPoint(wo, n, n, n, color, rng.integers(0, m, count))


def _pair(materials):
    numpy_lobe = MicrofacetReflection(materials, RenderSettings())
    compiled = MicrofacetReflection(materials, RenderSettings())
    compiled.use_backend(NUMBA)
    return numpy_lobe, compiled


def test_eval_and_sample_are_bit_identical():
    require_compiled()
    materials = _materials()
    numpy_lobe, compiled = _pair(materials)
    assert numpy_lobe.compiled is None and compiled.compiled is not None
    rng = np.random.default_rng(7)
    si = _hits(rng, len(materials), 4000)
    wi = rng.normal(size=(3, 4000))
    wi /= np.linalg.norm(wi, axis=0)                                # half of them below the surface
    f_a, p_a = numpy_lobe.eval(si, wi)
    f_b, p_b = compiled.eval(si, wi)
    assert (p_a > 0).sum() > 1000 and np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
    u = (rng.random(4000), rng.random(4000))
    a, b = numpy_lobe.sample(si, None, u), compiled.sample(si, None, u)
    assert (a.pdf > 0).sum() > 2000
    for x, y in ((a.wi, b.wi), (a.value, b.value), (a.pdf, b.pdf), (a.flags, b.flags)):
        assert np.array_equal(x, y)
    # Control: a lobe 1 ulp rougher is told apart.
    compiled.ax = np.nextafter(compiled.ax, 1.0)
    assert not np.array_equal(compiled.eval(si, wi)[1], p_a)


def test_principled_lobes_follow_the_backend():
    require_compiled()
    from engine.materials.principled import PrincipledV2
    from engine.scene.model import Material, Principled
    bsdf = PrincipledV2([Material("m", kind="principled", principled=Principled(metallic=0.5, coat_weight=0.5))],
                        RenderSettings())
    bsdf.use_backend({"principled": "numba"})
    assert bsdf.metal.compiled is not None and bsdf.specular.compiled is not None and bsdf.coat.compiled is not None
    bsdf.use_backend({"principled": "numpy"})
    assert bsdf.metal.compiled is None


def test_a_lobe_whose_fresnel_is_its_colour_is_bit_identical_on_a_take():
    """The Glossy BSDF's compiled eval (MicrofacetReflection.tinted) reads its hits by index: on the
    hits and on a take of a span's view, as the light samples evaluate."""
    require_compiled()
    materials = _materials()
    for m in materials:
        m.fresnel = "none"
    numpy_lobe, compiled = _pair(materials)
    assert compiled.tinted and not _pair(_materials())[1].tinted
    rng = np.random.default_rng(3)

    def hits():
        return _hits(np.random.default_rng(9), len(materials), 2000)[0:2000]
    wi = rng.normal(size=(3, 2000))
    wi /= np.linalg.norm(wi, axis=0)
    idx = np.sort(rng.integers(0, 2000, 1000))
    for take in (None, idx):
        at_a, at_b = hits(), hits()
        w = wi if take is None else wi.take(take, axis=1)
        f_a, p_a = numpy_lobe.eval(at_a if take is None else at_a.take(take), w)
        f_b, p_b = compiled.eval(at_b if take is None else at_b.take(take), w)
        assert (p_a > 0).sum() > 300 and np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
    # Control: a colour 1 ulp brighter is told apart.
    reference = compiled.eval(hits(), wi)[0]
    at = hits()
    at.color = np.nextafter(at.color, 2.0)
    assert not np.array_equal(compiled.eval(at, wi)[0], reference)


def test_frame_is_bit_identical():
    """microfacet_jit.frame against microfacet.py shading_frame: Gram-Schmidt of a tangent per hit or
    one for all, no tangent (orthonormal_basis), the fallback where the tangent is parallel to the
    normal or 0, normals at the poles and with z = -0.0; control: a normal 1 ulp off is told apart."""
    require_compiled()
    from engine.materials import microfacet_jit
    from engine.materials.microfacet import shading_frame
    rng = np.random.default_rng(23)
    n = rng.normal(size=(3, 600))
    n /= np.linalg.norm(n, axis=0)
    n[:, :10] = [[0.0], [0.0], [1.0]]
    n[:, 10:20] = [[0.0], [0.0], [-1.0]]
    n[:, 20:30] = [[1.0], [0.0], [-0.0]]
    t = rng.normal(size=(3, 600))
    t[:, 30:60] = 2.0 * n[:, 30:60]                    # parallel: the fallback
    t[:, 60:70] = 0.0
    for tangent in (None, t, np.array([1.0, 0.0, 0.0]), t[:, :1]):
        a, b = shading_frame(n, tangent), microfacet_jit.frame(n, tangent)
        assert all(x.shape == y.shape == (3, 600) and np.array_equal(x, y) for x, y in zip(a, b))
    off = n.copy()
    off[0] = np.nextafter(off[0], 2.0)
    assert not np.array_equal(microfacet_jit.frame(off, t)[1], shading_frame(n, t)[1])
    assert not np.array_equal(microfacet_jit.frame(off)[0], shading_frame(n)[0])
