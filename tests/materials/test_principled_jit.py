"""The compiled Principled v2 (engine/materials/principled_jit.py) against the NumPy path of
engine/materials/principled.py PrincipledV2: eval (on a span's hits and on a take of them, as the light
samples evaluate) and sample bit for bit, over metallic 0 to 1, roughness 0.02 to 1, anisotropy, specular
IOR level 0 (no specular lobe) to 1, tints, compensation on and off, colours above 1, Filter Glossy's
alpha floor and Reflective Caustics off, directions below the surface and at grazing.  Control: one
ulp of alpha is told apart.  The same with sheens and coats (tinted, of other IORs and roughnesses)
and alpha below 1 over those bases (controls: one ulp of the sheen's LTC a, of the coat's alpha);
the transmission closure (NumPy's lobe) added to them; a rough diffuse keeps the NumPy lobes."""
import numpy as np

from engine.core.settings import RenderSettings
from engine.materials.principled import PrincipledV2
from engine.materials.protocol import ShadingPoint
from engine.scene.model import Material, Principled
from tests.backend_capture import require_compiled

TWIN = "engine.materials.principled_jit"        # imported by use_backend, not here: numba may be missing
NUMBA = {"principled": "numba"}


def _materials():
    out = []
    for i, (metallic, rough, aniso, level) in enumerate([(0.0, 0.02, 0.0, 0.5), (1.0, 0.3, 0.0, 0.5),
                                                         (0.5, 1.0, 0.6, 0.8), (0.0, 0.5, 0.0, 0.0),
                                                         (0.3, 0.15, 0.9, 1.0), (1.0, 0.7, 0.2, 0.5)]):
        out.append(Material(f"m{i}", kind="principled", color=(0.9, 0.5 + 0.2 * i, 0.2), roughness=rough,
                            anisotropy=aniso, rotation=0.1 * i, multiscatter=i != 4,
                            principled=Principled(metallic=metallic, specular_ior_level=level,
                                                  specular_tint=(1.0, 0.8 + 0.05 * i, 0.7))))
    return out


def _hits(rng, m, count, extras=False):
    n = rng.normal(size=(3, count))
    n /= np.linalg.norm(n, axis=0)
    wo = rng.normal(size=(3, count))
    wo /= np.linalg.norm(wo, axis=0)
    wo = np.where((wo * n).sum(axis=0) < 0.0, -wo, wo)
    wo[:, :50] = n[:, :50]                                          # normal incidence
    graze = np.cross(n[:, 50:100].T, rng.normal(size=(50, 3))).T    # in the tangent plane
    wo[:, 50:100] = graze / np.linalg.norm(graze, axis=0)
    si = ShadingPoint(wo, n, n, n, 1.1 * rng.random((3, count)), rng.integers(0, m, count))
    if extras:
        si.alpha_floor = np.where(rng.random(count) < 0.5, 0.3, 0.0)
        si.glossy_off = rng.random(count) < 0.3
    return si[0:count]                          # a span's view: takes of it read its memo


def _pair(materials):
    numpy_bsdf = PrincipledV2(materials, RenderSettings())
    numpy_bsdf.use_backend({"principled": "numpy"})
    compiled = PrincipledV2(materials, RenderSettings())
    compiled.use_backend(NUMBA)
    return numpy_bsdf, compiled


def _check(numpy_bsdf, compiled, make_hits, rng, count=1500):
    wi = rng.normal(size=(3, count))
    wi /= np.linalg.norm(wi, axis=0)                                # half of them below the surface
    f_a, p_a = numpy_bsdf.eval(make_hits(), wi)
    f_b, p_b = compiled.eval(make_hits(), wi)
    assert (p_a > 0).sum() > 500 and np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
    idx = np.sort(rng.integers(0, count, count // 2))               # a take, as the light samples' hits
    f_a, p_a = numpy_bsdf.eval(make_hits().take(idx), wi.take(idx, axis=1))
    for filled in (True, False):       # the span's values computed before the take, or by the take's eval
        hits = make_hits()
        if filled:
            hits.memo((compiled, "fused"), compiled._fused_hits)    # the span's values, read by index
        f_b, p_b = compiled.eval(hits.take(idx), wi.take(idx, axis=1))
        assert np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
    u_lobe, u = rng.random(count), (rng.random(count), rng.random(count))
    a, b = numpy_bsdf.sample(make_hits(), u_lobe, u), compiled.sample(make_hits(), u_lobe, u)
    assert (a.pdf > 0).sum() > 500 and len(np.unique(a.flags)) == 2
    for x, y in ((a.wi, b.wi), (a.value, b.value), (a.pdf, b.pdf), (a.flags, b.flags)):
        assert np.array_equal(x, y)
    return wi


def test_eval_and_sample_are_bit_identical():
    require_compiled()
    materials = _materials()
    numpy_bsdf, compiled = _pair(materials)
    assert numpy_bsdf.compiled is None and compiled.compiled.__name__ == TWIN
    for extras in (False, True):
        wi = _check(numpy_bsdf, compiled, lambda: _hits(np.random.default_rng(11), len(materials), 1500, extras),
                    np.random.default_rng(5))
    # Control: a base 1 ulp rougher is told apart.
    hits = _hits(np.random.default_rng(11), len(materials), 1500)
    p_a = compiled.eval(hits, wi)[1]
    compiled.metal.ax = np.nextafter(compiled.metal.ax, 1.0)
    assert not np.array_equal(compiled.eval(_hits(np.random.default_rng(11), len(materials), 1500), wi)[1], p_a)


def _layered_materials():
    """The base's materials under coats (tinted, rough, of other IORs), sheens, alpha below 1, and
    both together."""
    out = _materials()
    for i, (coat, sheen, alpha) in enumerate([(0.5, 0.0, 1.0), (1.0, 0.7, 1.0), (0.0, 1.0, 1.0), (0.3, 0.4, 0.6),
                                              (2.0, 0.0, 1.0)]):
        base = out[i % len(out)]
        out.append(Material(f"l{i}", kind="principled", color=base.color, roughness=base.roughness,
                            anisotropy=base.anisotropy, rotation=base.rotation, multiscatter=base.multiscatter,
                            principled=Principled(metallic=base.principled.metallic, specular_tint=(1.0, 0.9, 0.8),
                                                  coat_weight=coat, coat_roughness=0.05 + 0.2 * i, coat_ior=1.3 + 0.2 * i,
                                                  coat_tint=(1.0, 1.0, 1.0) if i % 2 else (0.8, 0.6, 0.9),
                                                  sheen_weight=sheen, sheen_roughness=0.1 + 0.2 * i,
                                                  sheen_tint=(1.0, 0.7, 0.5), alpha=alpha)))
    return out


def test_layers_are_bit_identical():
    """The sheen and the coat over the base, compiled: eval (on the span and on a take) and the
    sample's mixture, the same bits as backend=numpy."""
    require_compiled()
    materials = _layered_materials()
    numpy_bsdf, compiled = _pair(materials)
    assert numpy_bsdf.compiled is None and compiled.compiled.__name__ == TWIN and compiled.any_layers
    count = 1500
    for extras in (False, True):
        def make_hits():
            return _hits(np.random.default_rng(13), len(materials), count, extras)
        rng = np.random.default_rng(9)
        wi = rng.normal(size=(3, count))
        wi /= np.linalg.norm(wi, axis=0)
        f_a, p_a = numpy_bsdf.eval(make_hits(), wi)
        f_b, p_b = compiled.eval(make_hits(), wi)
        assert (p_a > 0).sum() > 500 and np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
        idx = np.sort(rng.integers(0, count, count // 2))
        f_a, p_a = numpy_bsdf.eval(make_hits().take(idx), wi.take(idx, axis=1))
        for filled in (True, False):
            hits = make_hits()
            if filled:
                hits.memo((compiled, "fused"), compiled._fused_hits)
            f_b, p_b = compiled.eval(hits.take(idx), wi.take(idx, axis=1))
            assert np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
        u_lobe, u = rng.random(count), (rng.random(count), rng.random(count))
        a, b = numpy_bsdf.sample(make_hits(), u_lobe, u), compiled.sample(make_hits(), u_lobe, u)
        assert (a.pdf > 0).sum() > 500 and len(np.unique(a.flags)) >= 3
        for x, y in ((a.wi, b.wi), (a.value, b.value), (a.pdf, b.pdf), (a.flags, b.flags)):
            assert np.array_equal(x, y)
    # Controls: a sheen 1 ulp flatter (its LTC a), a coat 1 ulp rougher, are told apart.
    hits = make_hits()
    f_a = compiled.eval(hits, wi)[0]
    for lobe_change in ("sheen", "coat"):
        other = _pair(materials)[1]
        if lobe_change == "coat":
            other.coat.ax = np.nextafter(other.coat.ax, 1.0)
        else:
            table = other.sheen.params
            other.sheen.params = lambda si, r: (lambda a, b, c: (np.nextafter(a, 2.0), b, c))(*table(si, r))
        assert not np.array_equal(other.eval(make_hits(), wi)[0], f_a), lobe_change


def _transmitting_materials():
    """The layered materials and Principled glasses beside them: clear and rough, half transmitting
    over a metal or under a coat, index-matched (the delta pass-through), a rough diffuse of 0."""
    out = _layered_materials()
    for i, (t, rough, metallic, coat, ior) in enumerate([(1.0, 0.0, 0.0, 0.0, 1.45), (1.0, 0.3, 0.0, 0.0, 1.5),
                                                         (0.5, 0.2, 0.3, 0.0, 1.33), (0.7, 0.5, 0.0, 0.6, 1.6),
                                                         (1.0, 0.4, 0.0, 0.0, 1.0)]):
        out.append(Material(f"t{i}", kind="principled", color=(0.9, 0.7, 0.5 + 0.1 * i), roughness=rough, ior=ior,
                            multiscatter=i != 2,
                            principled=Principled(metallic=metallic, transmission_weight=t, coat_weight=coat,
                                                  specular_tint=(1.0, 0.9, 0.95))))
    return out


def test_transmission_is_bit_identical():
    """The transmission closure (NumPy's lobe) added to the compiled lobes: eval (on the span and on
    a take) and sample, the glass picks and the failed samples of every lobe, the same bits as
    backend=numpy.  Control: one ulp of the glass's alpha is told apart."""
    require_compiled()
    materials = _transmitting_materials()
    numpy_bsdf, compiled = _pair(materials)
    assert numpy_bsdf.compiled is None and compiled.compiled.__name__ == TWIN and compiled.any_transmission
    count = 3000
    for extras in (False, True):
        def make_hits():
            return _hits(np.random.default_rng(17), len(materials), count, extras)
        rng = np.random.default_rng(19)
        wi = rng.normal(size=(3, count))
        wi /= np.linalg.norm(wi, axis=0)
        f_a, p_a = numpy_bsdf.eval(make_hits(), wi)
        f_b, p_b = compiled.eval(make_hits(), wi)
        assert (p_a > 0).sum() > 1200 and np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
        idx = np.sort(rng.integers(0, count, count // 2))
        f_a, p_a = numpy_bsdf.eval(make_hits().take(idx), wi.take(idx, axis=1))
        for filled in (True, False):
            hits = make_hits()
            if filled:
                hits.memo((compiled, "fused"), compiled._fused_hits)
            f_b, p_b = compiled.eval(hits.take(idx), wi.take(idx, axis=1))
            assert np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
        u_lobe, u = rng.random(count), (rng.random(count), rng.random(count))
        a, b = numpy_bsdf.sample(make_hits(), u_lobe, u), compiled.sample(make_hits(), u_lobe, u)
        assert (a.pdf > 0).sum() > 1200 and len(np.unique(a.flags)) >= 5
        assert ((a.pdf == 0.0) & (a.flags != 0)).sum() > 10          # failed samples of some lobe
        for x, y in ((a.wi, b.wi), (a.value, b.value), (a.pdf, b.pdf), (a.flags, b.flags)):
            assert np.array_equal(x, y)
    other = _pair(materials)[1]
    other.glass.alpha = np.nextafter(other.glass.alpha, 1.0)
    assert not np.array_equal(other.eval(make_hits(), wi)[0], compiled.eval(make_hits(), wi)[0])


def test_a_rough_diffuse_keeps_the_numpy_lobes():
    require_compiled()
    rough = Material("r", kind="principled", diffuse_roughness=0.5, principled=Principled())
    bsdf = PrincipledV2(_materials() + [rough], RenderSettings())
    bsdf.use_backend(NUMBA)
    assert bsdf.compiled is None and bsdf.metal.compiled is not None
    coated = Material("c", kind="principled", principled=Principled(coat_weight=0.5))
    layered = PrincipledV2(_materials() + [coated], RenderSettings())
    layered.use_backend(NUMBA)
    assert layered.compiled is not None
    layered.use_backend({"principled": "numpy"})
    assert layered.compiled is None


def test_layered_probabilities_are_bit_identical():
    """_layered_lobes' closure weights and lobe probabilities from principled_jit.layered_probabilities
    against NumPy's, with and without a transmission closure and Reflective Caustics off; control: a
    layer 1 ulp more transparent is told apart."""
    require_compiled()
    for materials in (_layered_materials(), _transmitting_materials()):
        numpy_bsdf, compiled = _pair(materials)
        for extras in (False, True):
            layers_a, w_a, p_a = numpy_bsdf._layered_lobes(_hits(np.random.default_rng(29), len(materials), 2000,
                                                                 extras))
            layers_b, w_b, p_b = compiled._layered_lobes(_hits(np.random.default_rng(29), len(materials), 2000,
                                                               extras))
            assert len(w_a) == len(w_b) and p_a.shape == p_b.shape and np.array_equal(p_a, p_b)
            assert all(np.array_equal(x, y) for x, y in zip(w_a, w_b))
            assert (p_a[1:] > 0).sum(axis=1).min() > 20             # every lobe picked somewhere
        from engine.materials import principled_jit
        layers_b.through = np.nextafter(layers_b.through, 2.0)
        (w_metal, w_spec, w_diffuse), base = numpy_bsdf.lobe_weights(_hits(np.random.default_rng(29), len(materials),
                                                                           2000, True), sample_total=True)
        assert not np.array_equal(principled_jit.layered_probabilities(layers_b, w_metal, w_spec, w_diffuse, base)[1],
                                  p_a[:6])


def _opaque_beside_transmitting():
    """Opaque Principled BSDFs beside transmitting ones (full and partial Transmission, layered too)."""
    out = _materials()[:3]
    for i, (weight, coat) in enumerate([(1.0, 0.0), (0.6, 0.0), (1.0, 0.5)]):
        out.append(Material(f"t{i}", kind="principled", color=(0.9, 0.95, 1.0), roughness=0.1 + 0.2 * i,
                            principled=Principled(transmission_weight=weight, coat_weight=coat)))
    return out


def test_sample_and_eval_on_takes_of_mixed_transmitting_hits():
    """As the Mix Shader's leaves sample (always on a take of the span's hits): the compiled sample and
    eval on takes equal NumPy's, whether the span's own values were computed before the take or not.
    (The merge of branch principled3 failed this: its transmission setup, kept at the transmitting
    hits only, was read by hit index on takes: wrong values or an IndexError.)"""
    require_compiled()
    materials = _opaque_beside_transmitting()
    numpy_bsdf, compiled = _pair(materials)
    assert compiled.any_transmission
    count = 600
    make_hits = lambda: _hits(np.random.default_rng(3), len(materials), count)      # noqa: E731
    rng = np.random.default_rng(8)
    u_lobe, u = rng.random(count), (rng.random(count), rng.random(count))
    wi = rng.normal(size=(3, count))
    wi /= np.linalg.norm(wi, axis=0)
    checked = 0
    for idx in (np.arange(0, count, 3), np.sort(rng.choice(count, count // 2, replace=False)), np.arange(count)):
        a = numpy_bsdf.sample(make_hits().take(idx), u_lobe.take(idx), (u[0].take(idx), u[1].take(idx)))
        f_a, p_a = numpy_bsdf.eval(make_hits().take(idx), wi.take(idx, axis=1))
        for filled in (False, True):
            hits = make_hits()
            if filled:                          # the span's values first, then the take reads them
                compiled.sample(hits, u_lobe, u)
            b = compiled.sample(hits.take(idx), u_lobe.take(idx), (u[0].take(idx), u[1].take(idx)))
            for x, y in ((a.wi, b.wi), (a.value, b.value), (a.pdf, b.pdf), (a.flags, b.flags)):
                assert np.array_equal(x, y)
            f_b, p_b = compiled.eval(hits.take(idx), wi.take(idx, axis=1))
            assert np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
            checked += int((a.pdf > 0).sum())
    assert checked > 1000
    # Control: the take's hits in another order are other hits: the comparison tells them apart.
    idx = np.arange(0, count, 3)
    a = numpy_bsdf.sample(make_hits().take(idx), u_lobe.take(idx), (u[0].take(idx), u[1].take(idx)))
    b = compiled.sample(make_hits().take(idx[::-1]), u_lobe.take(idx), (u[0].take(idx), u[1].take(idx)))
    assert not np.array_equal(a.value, b.value)
