"""The compiled rough dielectric lobe (engine/materials/dielectric_jit.py) against the NumPy path of
engine/materials/dielectric_lobe.py MicrofacetDielectric: sample and eval bit for bit over alpha
from the floor to 1, entering and leaving (eta > 1 and < 1, total internal reflection), separable
and height-correlated G2, glass and the Refraction BSDF, normal and grazing incidence, directions
on both sides; the Principled glass closure's coloured RealFresnel; the glass BSDFs' and the
Principled BSDF's use_backend reach the lobe; Beckmann hits to the rounding of exp and log (NumPy's
SIMD code against the C library's), recorded from a render of Beckmann rough glass too."""
import numpy as np

from engine.core.settings import RenderSettings
from engine.materials.dielectric import RoughGlass, RoughRefraction
from engine.materials.dielectric_lobe import MicrofacetDielectric, RealFresnel
from engine.scene.model import Material
from tests.backend_capture import require_compiled


def _inputs(rng, count):
    wo = rng.normal(size=(3, count))
    wo[2] = np.abs(wo[2])
    wo /= np.linalg.norm(wo, axis=0)
    wo[:, :40] = [[0.0], [0.0], [1.0]]                          # normal incidence
    wo[:, 40:80] = [[1.0], [0.0], [0.0]]                        # grazing
    wo[:, 80:100] = -wo[:, 80:100]                              # below: invalid
    wi = rng.normal(size=(3, count))
    wi /= np.linalg.norm(wi, axis=0)                            # half below: refraction
    alpha = np.clip(rng.random(count) ** 2, 1e-4, 1.0)
    eta = np.where(rng.random(count) < 0.5, 1.45, 1.0 / 1.45) * (1.0 + 0.3 * rng.random(count))
    separable = rng.random(count) < 0.3
    u = rng.random((3, count))
    return wo, wi, alpha, eta, separable, u


def _pair(reflection):
    from engine.materials import dielectric_jit
    numpy_lobe = MicrofacetDielectric(reflection=reflection)
    compiled = MicrofacetDielectric(reflection=reflection)
    compiled.compiled = dielectric_jit
    return numpy_lobe, compiled


def test_sample_and_eval_are_bit_identical():
    require_compiled()
    rng = np.random.default_rng(11)
    wo, wi, alpha, eta, separable, u = _inputs(rng, 2000)
    no_beckmann = np.zeros(2000, bool)
    for reflection in (True, False):
        numpy_lobe, compiled = _pair(reflection)
        for sep in (None, separable):
            a = numpy_lobe.sample(wo, alpha, eta, no_beckmann, u[0], u[1], u[2], separable=sep)
            b = compiled.sample(wo, alpha, eta, no_beckmann, u[0], u[1], u[2], separable=sep)
            assert a[4].sum() > 600 and a[3][a[4]].sum() > 150
            for x, y in zip(a, b):
                assert x.dtype == y.dtype and np.array_equal(x, y)
            f_a, p_a = numpy_lobe.eval(wo, wi, alpha, eta, no_beckmann, sep)
            f_b, p_b = compiled.eval(wo, wi, alpha, eta, no_beckmann, sep)
            assert (p_a > 0).sum() > 100 and np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
    # Control: a lobe 1 ulp rougher is told apart.
    rougher = np.nextafter(alpha, 2.0)
    assert not np.array_equal(compiled.eval(wo, wi, rougher, eta, no_beckmann)[1],
                              numpy_lobe.eval(wo, wi, alpha, eta, no_beckmann)[1])
    assert not np.array_equal(compiled.sample(wo, rougher, eta, no_beckmann, u[0], u[1], u[2])[1],
                              numpy_lobe.sample(wo, alpha, eta, no_beckmann, u[0], u[1], u[2])[1])


def _real_fresnel(rng, eta, count):
    """RealFresnel (the Principled glass closure's) of a coloured F0 and tint; some hits untinted
    (T = 0) and index-matched (eta 1: F0 0)."""
    f0 = np.clip(rng.random((3, count)) * 0.2, 0.0, 1.0)
    tint = np.sqrt(rng.random((3, count)))
    tint[:, 100:150] = 0.0
    eta = eta.copy()
    eta[150:170] = 1.0
    return eta, RealFresnel(eta, f0, tint)


def test_coloured_real_fresnel_is_bit_identical():
    require_compiled()
    rng = np.random.default_rng(17)
    wo, wi, alpha, eta, separable, u = _inputs(rng, 3000)
    eta, fresnel = _real_fresnel(rng, eta, 3000)
    no_beckmann = np.zeros(3000, bool)
    numpy_lobe, compiled = _pair(True)
    for sep in (None, separable):
        a = numpy_lobe.sample(wo, alpha, eta, no_beckmann, u[0], u[1], u[2], separable=sep, fresnel=fresnel)
        b = compiled.sample(wo, alpha, eta, no_beckmann, u[0], u[1], u[2], separable=sep, fresnel=fresnel)
        assert a[1].shape == (3, 3000) and a[4].sum() > 900 and a[3][a[4]].sum() > 300
        for x, y in zip(a, b):
            assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y)
        for reflection in (True, False):
            numpy_lobe, compiled = _pair(reflection)
            f_a, p_a = numpy_lobe.eval(wo, wi, alpha, eta, no_beckmann, sep, fresnel=fresnel)
            f_b, p_b = compiled.eval(wo, wi, alpha, eta, no_beckmann, sep, fresnel=fresnel)
            assert f_a.shape == f_b.shape == (3, 3000) and (p_a > 0).sum() > 200
            assert np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
        numpy_lobe, compiled = _pair(True)
    # Controls: an F0 one ulp larger, a tint one ulp smaller are told apart.
    brighter = RealFresnel(fresnel.eta, np.nextafter(fresnel.f0, 2.0), fresnel.tint)
    assert not np.array_equal(compiled.eval(wo, wi, alpha, eta, no_beckmann, fresnel=brighter)[0],
                              numpy_lobe.eval(wo, wi, alpha, eta, no_beckmann, fresnel=fresnel)[0])
    darker = RealFresnel(fresnel.eta, fresnel.f0, np.nextafter(fresnel.tint, -1.0))
    assert not np.array_equal(compiled.sample(wo, alpha, eta, no_beckmann, u[0], u[1], u[2], fresnel=darker)[1],
                              numpy_lobe.sample(wo, alpha, eta, no_beckmann, u[0], u[1], u[2], fresnel=fresnel)[1])


def test_coloured_albedo_is_bit_identical(monkeypatch):
    """dielectric_jit.albedo_coloured (the Principled glass closure's albedo estimate) against
    principled_glass.py PrincipledGlass._albedo's NumPy lines, mean(R + T) at cos clipped to [0, 1]:
    on random cosines, IORs (entering, leaving, index-matched) and colours, and at cos NaN, +-inf,
    -0.0, below 0 and above 1, eta NaN and 1, and no hits; control: an F0 one ulp larger is told
    apart.  The Principled BSDF's glass closure calls it on the numba backend (a spy), not on numpy."""
    require_compiled()
    from engine.materials import dielectric_jit
    from engine.materials.principled_glass import PrincipledGlass
    rng = np.random.default_rng(41)
    count = 2000
    _, _, _, eta, _, _ = _inputs(rng, count)
    eta, fresnel = _real_fresnel(rng, eta, count)
    cos = rng.uniform(-0.2, 1.2, count)
    cos[:6] = np.nan, np.inf, -np.inf, -0.0, 0.0, 1.0
    fresnel.eta = np.asarray(fresnel.eta, dtype=np.float64).copy()
    fresnel.eta[6:9] = np.nan, 1.0, 1.0
    glass = PrincipledGlass([Material("g", kind="principled")], np.array([1.0]), np.ones((3, 1)))
    for n in (count, 0):
        at = slice(0, n)
        part = RealFresnel(fresnel.eta[at], fresnel.f0[:, at], fresnel.tint[:, at])
        with np.errstate(invalid="ignore"):
            expected = glass._albedo(part.eta, part.f0, part.tint, cos[at])      # NumPy: no compiled lobe
        got = dielectric_jit.albedo_coloured(cos[at], part)
        assert got.shape == (n,) and np.array_equal(expected, got, equal_nan=True)
        assert np.array_equal(np.signbit(expected), np.signbit(got))
    brighter = RealFresnel(fresnel.eta, np.nextafter(fresnel.f0, 2.0), fresnel.tint)
    assert not np.array_equal(dielectric_jit.albedo_coloured(cos, brighter), glass._albedo(
        fresnel.eta, fresnel.f0, fresnel.tint, cos), equal_nan=True)
    from engine.materials.principled import PrincipledV2
    from engine.scene.model import Principled
    calls = []
    kernel = dielectric_jit.albedo_coloured

    def spy(*args):
        calls.append(len(args[0]))
        return kernel(*args)
    monkeypatch.setattr(dielectric_jit, "albedo_coloured", spy)
    bsdf = PrincipledV2([Material("g", kind="principled", principled=Principled(transmission_weight=1.0))],
                        RenderSettings())
    for backend, called in (("numpy", []), ("numba", [count])):
        bsdf.use_backend({"principled": backend})
        calls.clear()
        with np.errstate(invalid="ignore"):
            got = bsdf.glass._albedo(fresnel.eta, fresnel.f0, fresnel.tint, cos)
        assert calls == called and np.array_equal(got, glass._albedo(fresnel.eta, fresnel.f0, fresnel.tint, cos),
                                                  equal_nan=True), backend


def test_principled_glass_follows_the_backend():
    require_compiled()
    from engine.materials.principled import PrincipledV2
    from engine.scene.model import Principled
    glass = Material("g", kind="principled", roughness=0.3, ior=1.5,
                     principled=Principled(transmission_weight=1.0))
    bsdf = PrincipledV2([glass], RenderSettings())
    for name in ("principled", "mix"):
        bsdf.use_backend({name: "numba"})
        assert bsdf.glass.lobe.compiled is not None
        bsdf.use_backend({name: "numpy"})
        assert bsdf.glass.lobe.compiled is None


def test_beckmann_hits_agree_to_exp_rounding():
    """Beckmann hits (mixed with GGX ones) compiled: their exp and log are the C library's, NumPy's
    its SIMD code's, so sample and eval agree to 1e-9 relative (the measured 5e-11: the slope's
    erfinv, near 0), the same lobes chosen and the same validity; GGX hits stay bit for bit."""
    require_compiled()
    rng = np.random.default_rng(3)
    wo, wi, alpha, eta, separable, u = _inputs(rng, 3000)
    beckmann = rng.random(3000) < 0.7
    for reflection in (True, False):
        numpy_lobe, compiled = _pair(reflection)
        for sep in (None, separable):
            with np.errstate(all="ignore"):
                a = numpy_lobe.sample(wo, alpha, eta, beckmann, u[0], u[1], u[2], separable=sep)
            b = compiled.sample(wo, alpha, eta, beckmann, u[0], u[1], u[2], separable=sep)
            assert a[4][beckmann].sum() > 1000 and np.array_equal(a[3], b[3]) and np.array_equal(a[4], b[4])
            assert all(np.array_equal(x[..., ~beckmann], y[..., ~beckmann]) for x, y in zip(a, b))
            assert all(_within(x, y, 1e-9) for x, y in zip(a[:3], b[:3]))
            with np.errstate(all="ignore"):
                f_a, p_a = numpy_lobe.eval(wo, wi, alpha, eta, beckmann, sep)
            f_b, p_b = compiled.eval(wo, wi, alpha, eta, beckmann, sep)
            assert (p_a[beckmann] > 0).sum() > 100 and _within(f_a, f_b, 1e-12) and _within(p_a, p_b, 1e-12)
    # Control: alpha 1e-9 rougher at the Beckmann hits is told apart at these tolerances.
    rougher = np.where(beckmann, alpha * (1.0 + 1e-9), alpha)
    with np.errstate(all="ignore"):                     # the reference's Lambda at w = 0 (its inf * False)
        assert not _within(compiled.sample(wo, rougher, eta, beckmann, u[0], u[1], u[2])[1],
                           numpy_lobe.sample(wo, alpha, eta, beckmann, u[0], u[1], u[2])[1], 1e-9)
        assert not _within(compiled.eval(wo, wi, rougher, eta, beckmann)[1],
                           numpy_lobe.eval(wo, wi, alpha, eta, beckmann)[1], 1e-12)


def _within(a, b, rel):
    """The same where a is not finite, else |a - b| <= rel |a|."""
    finite = np.isfinite(a)
    return np.array_equal(a[~finite], b[~finite], equal_nan=True) and bool(
        np.all(np.abs(a[finite] - b[finite]) <= rel * np.abs(a[finite])))


def test_other_fresnels_stay_numpy():
    require_compiled()
    rng = np.random.default_rng(3)
    wo, wi, alpha, eta, separable, u = _inputs(rng, 200)
    numpy_lobe, compiled = _pair(True)

    def fresnel(c):
        return np.stack([c, c, c]), np.stack([1.0 - c] * 3)
    no_beckmann = np.zeros(200, bool)
    f_a = numpy_lobe.eval(wo, wi, alpha, eta, no_beckmann, fresnel=fresnel)[0]
    assert f_a.shape == (3, 200) and np.array_equal(f_a, compiled.eval(wo, wi, alpha, eta, no_beckmann,
                                                                         fresnel=fresnel)[0])


def test_glass_bsdfs_follow_the_backend():
    require_compiled()
    for cls in (RoughGlass, RoughRefraction):
        bsdf = cls([Material("g", kind="glass", roughness=0.3, ior=1.5)], RenderSettings())
        for name in ("rough_glass", "refraction", "filter_glossy"):
            bsdf.use_backend({name: "numba"})
            assert bsdf.lobe.compiled is not None
            bsdf.use_backend({name: "numpy"})
            assert bsdf.lobe.compiled is None


def _recorded_calls(limit=6, beckmann=False):
    """Up to `limit` calls of MicrofacetDielectric.sample and .eval (their arguments, copied) from a
    16 x 16, 2 spp NumPy render of the built-in Cornell box with Filter Glossy 1 (its glass after a
    blurry bounce scatters as this lobe: engine/integrators/delta_blur.py); beckmann: its glass
    Beckmann rough glass of roughness 0.35 (sample_blends/rough_glass.blend's "Ground glass")."""
    import dataclasses
    from engine import api
    from engine.scene.builtin import BUILTIN_SCENES
    scene = BUILTIN_SCENES["cornell"]((16, 16))
    if beckmann:
        scene.materials = [dataclasses.replace(m, roughness=0.35, distribution="beckmann") if m.kind == "glass" else m
                           for m in scene.materials]
    calls = {"sample": [], "eval": []}
    originals = {name: getattr(MicrofacetDielectric, name) for name in calls}

    def recorder(name):
        def record(self, *args, **kwargs):
            if len(calls[name]) < limit:
                copied = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
                calls[name].append((self.reflection, self.transmission, copied, dict(kwargs)))
            return originals[name](self, *args, **kwargs)
        return record
    for name in calls:
        setattr(MicrofacetDielectric, name, recorder(name))
    try:
        api.render(scene, RenderSettings(samples=2, threads=1, backend="numpy", filter_glossy=1.0), log=lambda m: None)
    finally:
        for name, original in originals.items():
            setattr(MicrofacetDielectric, name, original)
    return calls


def _replayed(calls):
    """(NumPy's result, the compiled lobe's result) of each recorded call, and the compiled lobe of the
    first sample call (for the controls)."""
    from engine.materials import dielectric_jit
    pairs, first = [], None
    for name, recorded in calls.items():
        for reflection, transmission, args, kwargs in recorded:
            compiled = MicrofacetDielectric(reflection, transmission)
            compiled.compiled = dielectric_jit
            pairs.append((getattr(MicrofacetDielectric(reflection, transmission), name)(*args, **kwargs),
                          getattr(compiled, name)(*args, **kwargs)))
            if first is None and name == "sample":
                first = compiled, args, kwargs
    return pairs, first


def test_recorded_render_inputs_are_bit_identical():
    require_compiled()
    calls = _recorded_calls()
    assert calls["sample"] and calls["eval"]
    pairs, (lobe, args, kwargs) = _replayed(calls)
    for a, b in pairs:
        assert all(x.dtype == y.dtype and np.array_equal(x, y) for x, y in zip(a, b))
    # Control: the recorded hits 1 ulp rougher are told apart.
    rougher = [args[0], np.nextafter(args[1], 2.0)] + args[2:]
    reference = MicrofacetDielectric(lobe.reflection, lobe.transmission).sample(*args, **kwargs)[2]
    assert not np.array_equal(lobe.sample(*rougher, **kwargs)[2], reference)


def test_recorded_beckmann_inputs_agree_to_exp_rounding():
    require_compiled()
    calls = _recorded_calls(beckmann=True)
    assert calls["sample"] and calls["eval"] and all(args[3].all() for _, _, args, _ in calls["sample"])
    pairs, (lobe, args, kwargs) = _replayed(calls)
    for a, b in pairs:
        assert all(x.dtype == y.dtype for x, y in zip(a, b))
        assert all(np.array_equal(x, y) if x.dtype == bool else _within(x, y, 1e-9) for x, y in zip(a, b))
    # Control: the recorded hits 1e-9 rougher are told apart.
    rougher = [args[0], args[1] * (1.0 + 1e-9)] + args[2:]
    reference = MicrofacetDielectric(lobe.reflection, lobe.transmission).sample(*args, **kwargs)[2]
    assert not _within(lobe.sample(*rougher, **kwargs)[2], reference, 1e-9)


def test_energy_scale_is_bit_identical():
    """The multiscatter GGX glass's compensation (dielectric.py energy_scale, its albedo tables read
    compiled): made-up points over the tables' edges (roughness 0 and 1, mu outside [0, 1], eta 1,
    entering and leaving, tints 0 and 1) and the points of a NumPy render of multiscatter rough glass."""
    require_compiled()
    import dataclasses
    from engine import api
    from engine.materials import dielectric, dielectric_jit
    from engine.scene.builtin import BUILTIN_SCENES
    rng = np.random.default_rng(41)
    count = 3000
    roughness, mu = rng.random(count), rng.uniform(-0.2, 1.2, count)
    roughness[:100], roughness[100:200] = 0.0, 1.0
    eta = np.where(rng.random(count) < 0.5, 1.5, 1.0 / 1.5) * (1.0 + rng.random(count))
    eta[:50] = 1.0
    tint = rng.random((3, count))
    tint[:, 200:300], tint[:, 300:400] = 1.0, 0.0
    calls = [(roughness, mu, eta, tint)]
    original = dielectric.energy_scale

    def record(*args):
        calls.append(tuple(np.array(a, copy=True) for a in args))
        return original(*args)
    scene = BUILTIN_SCENES["cornell"]((16, 16))
    scene.materials = [dataclasses.replace(m, roughness=0.7, distribution="multi_ggx") if m.kind == "glass" else m
                       for m in scene.materials]
    dielectric.energy_scale = record
    try:
        api.render(scene, RenderSettings(samples=2, threads=1, backend="numpy"), log=lambda m: None)
    finally:
        dielectric.energy_scale = original
    assert len(calls) > 2
    for args in calls:
        a, b = original(*args), dielectric_jit.energy_scale(*args)
        assert a.shape == b.shape == (3, len(args[0])) and np.array_equal(a, b)
    # Control: a tint 1 ulp darker is told apart.
    darker = calls[-1][:3] + (np.nextafter(calls[-1][3], -1.0),)
    assert not np.array_equal(dielectric_jit.energy_scale(*darker), original(*calls[-1]))


def test_energy_scale_off_the_tables_is_nan_on_both_backends():
    """A point off the albedo tables (a NaN roughness, mu or eta, an infinite eta: a NaN table
    coordinate; NumPy's reads raised an IndexError there, numba's read out of bounds) gives NaN on
    both, its tables not read; mu and roughness beyond [0, 1] (inf too) are clipped onto them and
    read; -0.0 is 0.  Empty inputs give (3, 0).  Control: a kernel that read such a point at the
    tables' edge instead (a finite scale) is told apart."""
    require_compiled()
    from engine.materials import dielectric, dielectric_jit
    nan, inf = np.nan, np.inf
    roughness = np.array([0.5, nan, 0.5, 0.5, 0.5, 0.5, 0.5, inf, -0.0, 0.5, 0.3])
    mu = np.array([0.5, 0.5, nan, 0.5, 0.5, 0.5, inf, 0.5, 0.5, -inf, -0.0])
    eta = np.array([1.5, 1.5, 1.5, nan, inf, -inf, 1.5, 1.5, 0.7, 0.7, 1.0])
    tint = np.full((3, len(eta)), 0.8)
    tint[:, 0] = nan, -0.0, inf
    off = np.isnan(roughness) | np.isnan(mu) | ~np.isfinite(eta)
    with np.errstate(invalid="ignore"):                                 # NumPy's inf / inf of the inf tint
        a = dielectric.energy_scale(roughness, mu, eta, tint)
    b = dielectric_jit.energy_scale(roughness, mu, eta, tint)
    assert np.array_equal(a, b, equal_nan=True)
    assert np.isnan(a[:, off]).all() and np.isfinite(a[:, ~off][:, 1:]).all() and np.isnan(a[0, 0])
    empty = np.empty(0)
    assert dielectric_jit.energy_scale(empty, empty, empty, np.empty((3, 0))).shape == (3, 0)
    assert dielectric.energy_scale(empty, empty, empty, np.empty((3, 0))).shape == (3, 0)
    # Control: the off points read at the tables' edge (roughness 0, mu 0, eta 1) are told apart.
    with np.errstate(invalid="ignore"):
        edge = dielectric.energy_scale(np.where(off, 0.0, roughness), np.where(off, 0.0, mu),
                                       np.where(off, 1.0, eta), tint)
    assert not np.array_equal(edge, b, equal_nan=True)
