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
from engine.materials.media import MEDIUM_STACK_DEPTH, MediumStack
from engine.materials.principled import PrincipledV2
from engine.materials.protocol import BSDFFlags, ShadingPoint
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


def _hits(rng, m, count, extras=False, media=None):
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
    si.media = media                            # the paths' medium stacks (Nested Dielectrics), or None
    return si[0:count]                          # a span's view: takes of it read its memo


def _pair(materials):
    numpy_bsdf = PrincipledV2(materials, RenderSettings())
    numpy_bsdf.use_backend({"principled": "numpy"})
    compiled = PrincipledV2(materials, RenderSettings())
    compiled.use_backend(NUMBA)
    return numpy_bsdf, compiled


def _check(numpy_bsdf, compiled, make_hits, rng, count=1500, kinds=(2,)):
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
    assert (a.pdf > 0).sum() > 500 and len(np.unique(a.flags)) in kinds        # the kinds of lobes picked
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


def test_no_compensation_and_no_layer_at_the_hits():
    """Materials that do not compensate (the compiled lobes multiply by no compensation array) beside a
    transmitting one (the layered path) whose hits have no sheen nor coat (layer_weights' `bare`: no
    sheen or coat pass in base_eval; alpha 1, 0.5 and 0.3 there, with and without transmission): eval
    on the span and on a take, and sample, the same bits as backend=numpy.  Controls: the metal's
    clipped edge tint (from which the kernel makes its F82 b) 1 ulp off, and a compensation of 1 + 1 ulp
    where there is none, are told apart."""
    require_compiled()
    from dataclasses import replace
    materials = [replace(m, multiscatter=False) for m in _materials()]
    materials.append(Material("t", kind="principled", color=(0.9, 0.95, 1.0), roughness=0.2, multiscatter=False,
                              principled=Principled(transmission_weight=0.8, metallic=0.2)))
    materials += _see_through(True, multiscatter=False)
    numpy_bsdf, compiled = _pair(materials)
    assert compiled.any_transmission and not compiled.coat_weight.any() and not compiled.sheen_weight.any()
    for extras in (False, True):
        def make_hits():
            return _hits(np.random.default_rng(23), len(materials), 1500, extras)
        hits = make_hits()
        fused = compiled._fused_hits(hits)
        assert compiled._lobes_at(hits)[0].bare and not fused.over_base
        assert (compiled.alpha[hits.material] < 1.0).sum() > 200
        assert fused.comp_metal is None and fused.comp_spec is None and fused.any_metal
        wi = _check(numpy_bsdf, compiled, make_hits, np.random.default_rng(7), kinds=(3, 4))   # the glass's too
    f_a = compiled.eval(make_hits(), wi)[0]
    for change in ("tint", "scale"):
        other = _pair(materials)[1]
        if change == "tint":
            other.metal_tint = np.nextafter(other.metal_tint, -1.0)
        else:
            other.metal._compensation_terms_at = lambda at: (np.full((3, len(at)), np.nextafter(1.0, 2.0)),
                                                             np.ones(len(at)))
        assert not np.array_equal(other.eval(make_hits(), wi)[0], f_a)


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


def _see_through(transmission, multiscatter=True):
    """Materials without a sheen or a coat and of alpha below 1 (their hits are layer_weights' `bare`
    ones, where the kernel reads alpha for W): an opaque one of alpha 0.5 and one of alpha 0.3, with a
    transmission closure where `transmission`."""
    return [Material("a0", kind="principled", color=(0.7, 0.4, 0.2), roughness=0.3, multiscatter=multiscatter,
                     principled=Principled(metallic=0.4, alpha=0.5)),
            Material("a1", kind="principled", color=(0.7, 0.9, 0.8), roughness=0.1, multiscatter=multiscatter,
                     principled=Principled(transmission_weight=0.6 if transmission else 0.0, alpha=0.3))]


def test_layered_lobes_are_bit_identical():
    """_layered_lobes' closure weights and lobe probabilities from principled_jit.layered_lobes (the
    base's lobe weights and the layers' probabilities in one pass) against NumPy's, with and without a
    transmission closure and Reflective Caustics off, on hits with layers and on hits without any
    (layer_weights' `bare`: the kernel reads alpha for W; alpha 1, 0.5 and 0.3 there, with and without
    transmission); control: a layer 1 ulp more transparent is told apart."""
    require_compiled()
    for materials in (_layered_materials() + _see_through(False), _transmitting_materials() + _see_through(True)):
        numpy_bsdf, compiled = _pair(materials)
        for extras in (False, True):
            for bare in (False, True):
                def make_hits():
                    si = _hits(np.random.default_rng(29), len(materials), 2000, extras)
                    if bare:                # only the materials without a sheen or a coat
                        plain = np.flatnonzero((numpy_bsdf.sheen_weight == 0.0) & (numpy_bsdf.coat_weight == 0.0))
                        si.material[:] = plain[si.material % len(plain)]
                    return si
                layers_a, w_a, p_a = numpy_bsdf._layered_lobes(make_hits())
                layers_b, w_b, p_b = compiled._layered_lobes(make_hits())
                assert layers_a.bare == layers_b.bare == bare
                assert (numpy_bsdf.alpha[make_hits().material] < 1.0).sum() > 200    # alpha below 1, bare too
                assert len(w_a) == len(w_b) and p_a.shape == p_b.shape and np.array_equal(p_a, p_b)
                assert all(np.array_equal(x, y) for x, y in zip(w_a, w_b))
                assert (p_a[3:] > 0).sum(axis=1).min() > 20             # every base lobe picked somewhere
                assert bare or (p_a[1:] > 0).sum(axis=1).min() > 20     # and every layer
        from engine.materials import principled_jit
        si = _hits(np.random.default_rng(29), len(materials), 2000, True)
        layers, p_a = compiled.layer_weights(si), numpy_bsdf._layered_lobes(si)[2]
        glass = ()
        if compiled.any_transmission:
            glass = (compiled._glass_setup(si).w, compiled._glass_setup(si).sample_weight)
        assert np.array_equal(principled_jit.layered_lobes(compiled._compiled_lobe_inputs(si), layers, *glass)[1], p_a)
        layers.through = np.nextafter(layers.through, 2.0)
        assert not np.array_equal(principled_jit.layered_lobes(compiled._compiled_lobe_inputs(si), layers, *glass)[1],
                                  p_a)


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


def test_takes_that_reorder_the_transmitting_hits_under_nested_dielectrics():
    """Takes of exactly the transmitting hits in another order (as many hits as the transmission closure
    was set up at, none of them where it was: its setup is read by their rows) and with repeats, of
    paths in air and inside the glass (Nested Dielectrics): the compiled sample and eval equal NumPy's,
    and so do the medium stacks the sample crossed.  Control: the setup read whole wherever the take
    has as many transmitting hits as it (the shortcut the re-landed principled3 took) is told apart."""
    require_compiled()
    materials = _opaque_beside_transmitting()
    count = 600
    rng = np.random.default_rng(12)
    inside = rng.random(count) < 0.5
    ior = 1.0 + 0.5 * inside

    def make_hits():
        stacks = MediumStack(np.tile(ior[:, None], (1, MEDIUM_STACK_DEPTH)), inside.astype(np.int64))
        return _hits(np.random.default_rng(4), len(materials), count, media=stacks)
    transmitting = np.flatnonzero(make_hits().material >= 3)
    u_lobe, u = rng.random(count), (rng.random(count), rng.random(count))
    wi = rng.normal(size=(3, count))
    wi /= np.linalg.norm(wi, axis=0)

    def compare(numpy_bsdf, compiled, idx, filled):
        """Whether the compiled sample and eval at the take idx equal NumPy's (stacks too)."""
        uv = (u[0].take(idx), u[1].take(idx))
        a_hits = make_hits().take(idx)
        a = numpy_bsdf.sample(a_hits, u_lobe.take(idx), uv)
        f_a, p_a = numpy_bsdf.eval(make_hits().take(idx), wi.take(idx, axis=1))
        hits = make_hits()
        if filled:                              # the span's values first, then the take reads them
            hits.memo((compiled, "fused"), compiled._fused_hits)
        b_hits = hits.take(idx)
        b = compiled.sample(b_hits, u_lobe.take(idx), uv)
        f_b, p_b = compiled.eval(make_hits().take(idx), wi.take(idx, axis=1))
        same = [np.array_equal(x, y) for x, y in ((a.wi, b.wi), (a.value, b.value), (a.pdf, b.pdf),
                                                   (a.flags, b.flags), (f_a, f_b), (p_a, p_b),
                                                   (a_hits.media.media, b_hits.media.media),
                                                   (a_hits.media.depth, b_hits.media.depth))]
        return all(same), a
    numpy_bsdf, compiled = _pair(materials)
    crossed = 0
    for idx in (transmitting[::-1].copy(), np.roll(transmitting, 7), np.repeat(transmitting[::2], 2)):
        for filled in (False, True):
            same, a = compare(numpy_bsdf, compiled, idx, filled)
            assert same
            crossed += int(((a.flags & BSDFFlags.TRANSMISSION) != 0).sum())
    assert crossed > 300
    # Control: the setup read whole where as many hits transmit as it was set up at.
    glass_rows = compiled._glass_rows
    compiled._glass_rows = lambda glass, at: (glass.setup if len(at) == len(glass.setup) else glass_rows(glass, at))
    assert not compare(numpy_bsdf, compiled, transmitting[::-1].copy(), True)[0]


def _principled_cornell():
    """The built-in Cornell box in Principled materials, as sample_blends/principled.blend builds it
    (diffuse walls, the mirror a metal, the glass transmitting), the blue block coated with a sheen
    and the red wall's specular at its IOR level 0.5."""
    from dataclasses import replace
    from engine.scene.builtin import BUILTIN_SCENES
    scene = BUILTIN_SCENES["cornell"]((16, 16))
    extra = {"Mirror": dict(metallic=1.0), "Glass": dict(transmission_weight=1.0),
             "Blue": dict(coat_weight=0.6, sheen_weight=0.5), "Red": dict(specular_ior_level=0.5)}
    rough = {"Mirror": 0.05, "Glass": 0.1}
    scene.materials = [replace(m, kind="principled", roughness=rough.get(m.name, 0.5), ior=1.5,
                               principled=Principled(**{"specular_ior_level": 0.0, **extra.get(m.name, {})}))
                       for m in scene.materials]
    return scene


def _recorded_principled_hits(limit=6):
    """[(ShadingPoint fields, u_lobe, u1, u2)] of PrincipledV2.sample in a 16 x 16, 2 spp NumPy render
    of _principled_cornell."""
    from engine import api
    calls, original = [], PrincipledV2.sample

    def recording(self, si, u_lobe, u):
        if len(calls) < limit:
            calls.append(([np.array(getattr(si, f)) for f in ("wo", "n", "ng", "normal", "color", "material")],
                          np.array(u_lobe), u[0].copy(), u[1].copy()))
        return original(self, si, u_lobe, u)
    PrincipledV2.sample = recording
    try:
        scene = _principled_cornell()
        api.render(scene, RenderSettings(samples=2, threads=1, backend="numpy"), log=lambda m: None)
    finally:
        PrincipledV2.sample = original
    return scene, calls


def test_recorded_hits_are_bit_identical():
    """On the hits of a real render (a Principled Cornell box with a metal, a glass, a coat and a
    sheen): sample, eval at the sampled directions and at a take, lobe_weights, the same bits as
    backend=numpy.  Control: the compiled glass's setup read one hit off is told apart."""
    require_compiled()
    scene, calls = _recorded_principled_hits()
    assert len(calls) >= 4
    numpy_bsdf, compiled = _pair(scene.materials)
    picked = set()
    for fields, u_lobe, u1, u2 in calls:
        def make_hits():
            return ShadingPoint(*(a.copy() for a in fields))[0:len(u1)]
        a, b = numpy_bsdf.sample(make_hits(), u_lobe, (u1, u2)), compiled.sample(make_hits(), u_lobe, (u1, u2))
        for x, y in ((a.wi, b.wi), (a.value, b.value), (a.pdf, b.pdf), (a.flags, b.flags)):
            assert np.array_equal(x, y)
        picked |= set(np.unique(a.flags).tolist())
        f_a, p_a = numpy_bsdf.eval(make_hits(), a.wi)
        assert all(np.array_equal(x, y) for x, y in zip((f_a, p_a), compiled.eval(make_hits(), a.wi)))
        idx = np.arange(0, len(u1), 3)
        f_a, p_a = numpy_bsdf.eval(make_hits().take(idx), a.wi.take(idx, axis=1))
        hits = make_hits()
        hits.memo((compiled, "fused"), compiled._fused_hits)
        f_b, p_b = compiled.eval(hits.take(idx), a.wi.take(idx, axis=1))
        assert np.array_equal(f_a, f_b) and np.array_equal(p_a, p_b)
    assert len(picked) >= 4                                         # diffuse, glossy, sheen, the glass's
    # Control: the transmission closure's setup read one hit off (its rows rolled).
    fields, u_lobe, u1, u2 = max(calls, key=lambda c: (c[0][5] == 5).sum())      # the most glass hits
    other = _pair(scene.materials)[1]
    glass_rows = other._glass_rows
    other._glass_rows = lambda glass, at: glass_rows(glass, np.roll(at, 1))
    wi = compiled.sample(ShadingPoint(*(a.copy() for a in fields)), u_lobe, (u1, u2)).wi
    idx = np.arange(len(u1))[::-1].copy()             # the light samples' take: the setup read by index
    f_cos = []
    for bsdf in (compiled, other):
        hits = ShadingPoint(*(a.copy() for a in fields))[0:len(u1)]
        hits.memo((bsdf, "fused"), bsdf._fused_hits)
        f_cos.append(bsdf.eval(hits.take(idx), wi.take(idx, axis=1))[0])
    assert not np.array_equal(*f_cos)


def test_lobe_weights_at_edge_inputs():
    """The compiled lobe_weights (principled_jit.py) against NumPy's on colours NaN, inf, -0.0, 0 and
    above 1, metallic 0 and 1, Reflective Caustics off, with and without a transmission closure and
    compensation, and on no hits at all, and so layered_lobes (the layered materials' weights and
    probabilities); control: an s(mu) table 1 ulp off is told apart."""
    require_compiled()
    for materials in (_materials(), _transmitting_materials()):
        numpy_bsdf, compiled = _pair(materials)
        for count in (0, 600):
            si = _hits(np.random.default_rng(31), len(materials), max(count, 100), extras=True)
            if count == 0:
                si = si.take(np.empty(0, dtype=np.int64))
            else:
                si.color[0, :20], si.color[1, 20:40], si.color[2, 40:60] = np.nan, np.inf, -np.inf
                si.color[:, 60:80], si.color[:, 80:90] = -0.0, 0.0
            for total in (False, True):
                with np.errstate(invalid="ignore"):             # NumPy's NaN colours
                    (wa, pa), (wb, pb) = numpy_bsdf.lobe_weights(si, total), compiled.lobe_weights(si, total)
                assert all(_same(x, y) for x, y in zip((*wa, pa), (*wb, pb)))
                assert count == 0 or (np.isnan(pa).any() and (pa > 0).sum() > 200)
            if numpy_bsdf.any_layers:               # the same kernel's layered mode (layered_lobes)
                with np.errstate(invalid="ignore"):
                    (_, wa, pa), (_, wb, pb) = numpy_bsdf._layered_lobes(si), compiled._layered_lobes(si)
                assert all(_same(x, y) for x, y in zip((*wa, pa), (*wb, pb)))
                assert count == 0 or (np.isnan(pa).any() and (pa > 0).sum() > 200)
    si = _hits(np.random.default_rng(31), len(materials), 600)
    compiled.s_metal = np.nextafter(compiled.s_metal, 2.0)
    assert not np.array_equal(numpy_bsdf.lobe_weights(si, True)[1], compiled.lobe_weights(si, True)[1])


def _same(x, y) -> bool:
    """The same numbers, NaN where NaN, and the same signs (of zeros too)."""
    return np.array_equal(x, y, equal_nan=True) and np.array_equal(np.signbit(x), np.signbit(y))


def test_sample_values_at_edge_inputs():
    """principled_jit.sample_values against the lines of principled.py _layered_sample it replaces,
    on f cos NaN, inf, -inf and -0.0, pdfs 0, -0.0, NaN and tiny, pass-throughs of probability 0,
    failed samples, and no hits; control: a pdf 1 ulp off is told apart."""
    require_compiled()
    from engine.materials import principled_jit
    rng = np.random.default_rng(41)

    def numpy_values(f_cos, pdf, choice, p_through, w_through, failed):
        through = np.flatnonzero(choice == 0)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            value = np.where(pdf > 0.0, f_cos / pdf, 0.0)
            value[:, through] = np.where(p_through[through] > 0.0, w_through[through] / p_through[through], 0.0)
        pdf = pdf.copy()
        pdf[through] = p_through[through]
        value[:, failed], pdf[failed] = 0.0, 0.0
        return np.nan_to_num(value), pdf

    for count in (0, 500):
        f_cos, pdf = rng.normal(size=(3, count)), rng.random(count)
        f_cos[0, :10], f_cos[1, 10:20], f_cos[2, 20:30], f_cos[:, 30:40] = np.nan, np.inf, -np.inf, -0.0
        pdf[40:50], pdf[50:60], pdf[60:70], pdf[70:80] = 0.0, -0.0, np.nan, 1e-320
        choice, failed = rng.integers(0, 7, count), rng.random(count) < 0.1
        p_through, w_through = rng.random(count), rng.random(count)
        p_through[:count // 10] = 0.0
        expected = numpy_values(f_cos, pdf, choice, p_through, w_through, failed)
        got = principled_jit.sample_values(f_cos.copy(), pdf.copy(), choice, p_through, w_through, failed)
        assert all(_same(x, y) for x, y in zip(expected, got))
        base = numpy_values(f_cos, pdf, np.ones(count, int), p_through, w_through, np.zeros(count, bool))
        assert all(_same(x, y) for x, y in zip(base, principled_jit.sample_values(f_cos.copy(), pdf.copy())))
    pdf[100] = np.nextafter(pdf[100], 2.0)
    assert not np.array_equal(expected[0], principled_jit.sample_values(f_cos.copy(), pdf.copy(), choice, p_through,
                                                                        w_through, failed)[0])


def test_textured_roughness_renders_the_same_bits():
    """A Principled plate whose roughness and metallic are read from a texture (lobe_weights with the
    hits' own s(mu), principled.py _textured_s) rendered on both backends: the same image bit for
    bit (float32 pixels).  Control: the compiled render of the plate 1e-6 more metallic is another image."""
    require_compiled()
    import dataclasses
    from engine import render
    from tests.materials.test_input_textures import SLOT, half_texture, plate_scene, principled
    material = dataclasses.replace(principled(roughness=0.5, metallic=0.3, color=(0.9, 0.6, 0.2)),
                                   input_textures={"roughness": SLOT})
    settings = RenderSettings(samples=4, seed=3, threads=1, parallelism="threads")

    def image(m, backend):
        scene = plate_scene([m], [half_texture(0.2, 0.8)], split=False)
        return render(scene, dataclasses.replace(settings, backend=backend), log=lambda *a: None).image
    reference = image(material, "numpy")
    assert reference.mean() > 0.01 and np.array_equal(reference, image(material, "numba"))
    more = dataclasses.replace(material, principled=Principled(metallic=0.3 + 1e-6))
    assert not np.array_equal(reference, image(more, "numba"))


def _no_hits(span: bool) -> ShadingPoint:
    z = np.zeros((3, 0))
    si = ShadingPoint(z, z.copy(), z.copy(), z.copy(), z.copy(), np.zeros(0, np.int64))
    return si[0:0] if span else si


def test_sample_and_eval_of_no_hits_with_a_transmitting_material():
    """No hits at all (a ShadingPoint of none, or an empty span of one) under a material set with a
    transmission closure: both backends return empty results.  (The re-landed compiled path first
    asked the closure's albedo estimate of a setup that was never made: AttributeError on numba;
    found by review of the principled4 merge.)"""
    require_compiled()
    numpy_bsdf, compiled = _pair(_opaque_beside_transmitting())
    for bsdf in (numpy_bsdf, compiled):
        for span in (False, True):
            f, pdf = bsdf.eval(_no_hits(span), np.zeros((3, 0)))
            assert f.shape == (3, 0) and pdf.shape == (0,)
            s = bsdf.sample(_no_hits(span), np.zeros(0), (np.zeros(0), np.zeros(0)))
            assert s.value.shape == (3, 0) and s.wi.shape == (3, 0)
