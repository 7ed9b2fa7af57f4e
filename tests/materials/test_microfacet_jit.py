"""The compiled GGX lobe geometry (engine/materials/microfacet_jit.py) against the NumPy path of
engine/materials/glossy.py MicrofacetReflection: eval and sample bit for bit, over roughness 0.02
to 1, anisotropy, every Fresnel kind, compensation on and off, directions below the surface and
at grazing; the BSDF protocol's use_backend reaches the Principled BSDF's lobes.  The Beckmann
functions (the rough glass's) to the rounding of exp and log, and their sampled slope's shortcut
bit for bit against the bisection."""
from types import SimpleNamespace

import numpy as np

from engine.core.settings import RenderSettings
from engine.materials.glossy import MicrofacetReflection
from engine.materials.microfacet import SQRT_PI
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


# -- Beckmann: exp and log are the C library's in the twin, NumPy's SIMD code (AVX512F) in the reference --
def _within(a, b, rel, floor=0.0):
    """a and b the same where a is not finite, else |a - b| <= rel max(|a|, floor) (floor 0: 0 only as 0)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    finite = np.isfinite(a)
    return (np.array_equal(a[~finite], b[~finite], equal_nan=True)
            and bool(np.all(np.abs(a[finite] - b[finite]) <= rel * np.maximum(np.abs(a[finite]), floor))))


def _beckmann_inputs(rng, count):
    """Directions (3, N) over the sphere, some along the normal, in the tangent plane, -0, NaN and inf;
    alphas from the floor to 1."""
    w = rng.normal(size=(3, count))
    w /= np.linalg.norm(w, axis=0)
    w[:, :20] = [[0.0], [0.0], [1.0]]
    w[:, 20:40] = [[0.6], [0.8], [0.0]]
    w[:, 40:45] = [[0.0], [-0.0], [-0.0]]
    w[:, 45:50] = [[np.nan], [0.0], [1.0]]
    w[:, 50:55] = [[np.inf], [0.0], [1.0]]
    alpha = np.clip(rng.random(count) ** 2, 1e-4, 1.0)
    return w, alpha


def test_beckmann_functions_agree_with_numpy_to_exp_rounding():
    require_compiled()
    from engine.materials import microfacet as mf
    from engine.materials import microfacet_jit as mj
    rng = np.random.default_rng(23)
    x = np.concatenate([rng.normal(size=5000) * 3.0, [0.0, -0.0, np.inf, -np.inf, np.nan, 1e-300, -40.0, 40.0]])
    assert _within(mf.erf(x), [mj.erf(v) for v in x], 1e-15, floor=1.0)        # 1 - t exp(...): absolute
    y = np.concatenate([rng.uniform(-1.0, 1.0, 5000), [0.0, -0.0, 1.0, -1.0, np.nan, 1.0 - 1e-12, 2.0]])
    with np.errstate(all="ignore"):
        reference = mf._erfinv(y)
    assert _within(reference, [mj.erfinv(v) for v in y], 1e-10)
    w, alpha = _beckmann_inputs(rng, 4000)
    with np.errstate(all="ignore"):
        d, lam = mf.beckmann_d(w, alpha, alpha), mf.beckmann_lambda(w, alpha, alpha)
    assert (d > 0).sum() > 1000 and (lam > 0).sum() > 1000
    assert _within(d, [mj.beckmann_d(*w[:, i], alpha[i], alpha[i]) for i in range(4000)], 1e-12)
    assert _within(lam, [mj.beckmann_lambda(*w[:, i], alpha[i], alpha[i]) for i in range(4000)], 1e-12)
    assert np.signbit(mj.erf(-0.0)) and mj.erf(-0.0) == mf.erf(np.array([-0.0]))[0]     # copysign keeps the sign
    # Controls: 1 ulp of alpha, a relative 1e-9 of x are told apart at these tolerances.
    assert not _within(d, [mj.beckmann_d(*w[:, i], alpha[i], np.nextafter(alpha[i], 2.0)) for i in range(4000)],
                       1e-15)
    assert not _within(mf.erf(x), [mj.erf(v * (1.0 + 1e-9)) for v in x], 1e-15, floor=1.0)


def test_beckmann_vndf_agrees_with_numpy():
    """The sampled normals of microfacet.py beckmann_sample_vndf, to its CDF's rounding (see below)."""
    require_compiled()
    from engine.materials import microfacet as mf
    from engine.materials import microfacet_jit as mj
    rng = np.random.default_rng(29)
    w, alpha = _beckmann_inputs(rng, 3000)
    w[2, 100:200] = np.abs(w[2, 100:200])
    u1, u2 = rng.random(3000), rng.random(3000)
    u1[:30], u2[30:60] = 0.0, 1.0 - 1e-12
    ay = alpha * np.where(rng.random(3000) < 0.3, 0.5, 1.0)          # anisotropic too
    with np.errstate(all="ignore"):
        h = mf.beckmann_sample_vndf(w, alpha, ay, u1, u2)
    h_jit = np.array([mj.beckmann_vndf(*w[:, i], alpha[i], ay[i], u1[i], u2[i]) for i in range(3000)]).T
    assert np.isfinite(h).sum() > 8000
    assert _within(h, h_jit, 1e-9)
    shifted = np.array([mj.beckmann_vndf(*w[:, i], alpha[i], ay[i], u1[i] * (1.0 + 1e-6), u2[i])
                        for i in range(3000)]).T
    assert not _within(h, shifted, 1e-9)                                   # control: u1 off by 1e-6


def test_visible_slope_is_the_bisection_bit_for_bit():
    """visible_slope skips the CDF where the side of the root is certain: the same result as the
    48-step bisection (the same exp), over normal to grazing incidence, u1 near 0 and 1, NaN."""
    require_compiled()
    from engine.materials import microfacet_jit as mj
    rng = np.random.default_rng(31)
    count = 20000
    cos = np.concatenate([rng.random(count // 2), 1.0 - rng.random(count // 4) ** 4 * 1e-3,
                          rng.random(count // 4) ** 6])
    sin = np.sqrt(1.0 - cos * cos)
    with np.errstate(divide="ignore"):
        k = np.where(sin > 1e-7, sin / (cos * SQRT_PI), 0.0)
        hi = np.minimum(np.where(sin > 1e-7, cos / sin, np.inf), 8.0)
    u = rng.random(count)
    u[:300], u[300:600] = rng.random(300) * 1e-9, 1.0 - rng.random(300) * 1e-9
    target = np.array([mj._slope_cdf(a, b) for a, b in zip(hi, k)]) * u
    target[600:610], k[610:620] = np.nan, -0.5                              # NaN; the lower hemisphere
    full = np.array([mj._bisect(*args) for args in zip(hi, k, target)])
    fast = np.array([mj.visible_slope(*args) for args in zip(hi, k, target)])
    assert np.array_equal(full, fast, equal_nan=True) and np.isfinite(full).sum() > count - 20
    # Control: the bisection tells a target 1e-12 larger apart (so equality is a real check).
    nudged = np.array([mj._bisect(a, b, c * (1.0 + 1e-12)) for a, b, c in zip(hi, k, target)])
    assert not np.array_equal(full, nudged, equal_nan=True)
