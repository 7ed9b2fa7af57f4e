"""The compiled glue of the wavefront (engine/integrators/wavefront_jit.py) against PathTracer's NumPy lines:
renders whose only compiled kernels are this module's (the Lambertian direct light, light_tests and
lambert_light, and the rest), with a control; the scatter stage's tail, the roulette and the compaction
in one pass (survivors, also with the deferred roulette) against PathTracer's scatter, roulette and
path_tracer.next_rays on recorded and made-up paths (NaN, huge offsets, both sides); the emission, the
misses, the bounce counts, the final groups, the facing normals and the path state's take."""
import copy
from types import SimpleNamespace

import numpy as np
import pytest

from engine import api
from engine.core.settings import RenderSettings
from engine.integrators import path_tracer
from engine.integrators.light_paths import LightPaths
from engine.scene.builtin import BUILTIN_SCENES
from tests.backend_capture import require_compiled

TWIN = "engine.integrators.wavefront_jit"       # imported after require_compiled(): numba may be missing


def same(a, b):
    """The same arrays: dtype, values (NaN where NaN) and the sign of every non-NaN value (-0.0 is not 0.0)."""
    def signs(x):
        return np.signbit(x) & ~np.isnan(x) if x.dtype.kind == "f" else x
    return all(x.dtype == y.dtype and np.array_equal(x, y, equal_nan=True) and np.array_equal(signs(x), signs(y))
               for x, y in zip(a, b))


def render_with(scene, twin, size=24):
    """The image of a one-thread NumPy-backend render of a built-in scene with `twin` as the path
    tracer's wavefront_jit (None: NumPy's glue)."""
    from engine.rendering import session
    original = session.PathTracer.__init__

    def with_twin(self, *args, **kwargs):
        original(self, *args, **kwargs)
        self.wavefront_jit = twin
    session.PathTracer.__init__ = with_twin
    try:
        return api.render(BUILTIN_SCENES[scene]((size, size)), RenderSettings(samples=4, threads=1, backend="numpy"),
                          log=lambda m: None).image
    finally:
        session.PathTracer.__init__ = original


@pytest.mark.parametrize("scene", ["caustic", "many_lights"])
def test_a_render_with_this_modules_kernels_alone_is_the_same(scene):
    require_compiled()
    from engine.integrators import wavefront_jit
    assert np.array_equal(render_with(scene, None), render_with(scene, wavefront_jit))


def test_a_render_with_a_direct_light_slightly_off_differs():
    """Control: the Lambertian direct light's kernel with its albedo 2^-20 too large changes the
    (float32) image."""
    require_compiled()
    from types import SimpleNamespace
    from engine.integrators import wavefront_jit

    def off(valid, blocked, cos_x, ls, p_b, reachable, mis, albedo, into=None):
        return wavefront_jit.lambert_light(valid, blocked, cos_x, ls, p_b, reachable, mis, albedo * (1.0 + 2.0 ** -20),
                                           into)
    wrong = SimpleNamespace(**dict(vars(wavefront_jit), lambert_light=off))
    assert not np.array_equal(render_with("cornell", None, 16), render_with("cornell", wrong, 16))


@pytest.mark.parametrize("scene", ["cornell", "many_lights"])
def test_recorded_direct_light_calls_are_bit_identical(scene):
    """PathTracer.direct_light on the calls of a real render, with and without this module (its
    Lambertian case compiled): the same float64 light, bit for bit; a control an ulp off differs."""
    require_compiled()
    from engine.integrators import wavefront_jit
    from engine.rendering import session
    calls, original = [], session.PathTracer.direct_light

    def recording(self, *args, **kwargs):
        calls.append((self, args, kwargs))
        return original(self, *args, **kwargs)
    session.PathTracer.direct_light = recording
    try:
        render_with(scene, None, 16)
    finally:
        session.PathTracer.direct_light = original
    assert len(calls) >= 4
    fused, lambert = [], session.PathTracer.lambert_direct_light

    def counted(self, *args):
        fused.append(1)
        return lambert(self, *args)
    session.PathTracer.lambert_direct_light = counted
    try:
        rng = np.random.default_rng(5)
        for tracer, args, kwargs in calls[:6]:
            kwargs = dict(kwargs, into=None)        # (the render's own into: its path state, since changed)
            tracer.wavefront_jit = None
            reference = original(tracer, *args, **kwargs)
            tracer.wavefront_jit = wavefront_jit
            compiled = original(tracer, *args, **kwargs)
            assert reference.dtype == compiled.dtype == np.float64 and np.array_equal(reference, compiled)
            assert (reference > 0).any() and not np.array_equal(reference, np.nextafter(compiled, np.inf))
            # The sum into the path state in place (PathTracer.bounce's): radiance += beta x light over the
            # hits' columns, the same as NumPy's; control: beta an ulp off.
            m = reference.shape[1]
            start, beta = rng.random((3, m + 7)), rng.random((3, m + 7))
            bounce = rng.integers(0, 2, m + 7).astype(np.int32)
            expected = start.copy()
            expected[:, 5:5 + m] += beta[:, 5:5 + m] * reference
            radiance, off = start.copy(), start.copy()
            assert original(tracer, *args, **dict(kwargs, into=(radiance, beta, 5, bounce, None))) is None
            assert np.array_equal(radiance, expected)
            original(tracer, *args, **dict(kwargs, into=(off, np.nextafter(beta, 2.0), 5, bounce, None)))
            assert not np.array_equal(off, expected)
            # Clamped (Light Paths' clamp: PathTracer.bounce's NumPy lines), Clamp Direct at bounce 0 only;
            # limits at the light's quantiles, so that some of both kinds are clamped and some are not.
            light = beta[:, 5:5 + m] * reference
            limits = tuple(float(np.quantile(np.abs(light).sum(axis=0), q)) / 3.0 for q in (0.5, 0.8))
            expected = start.copy()
            expected[:, 5:5 + m] += LightPaths.clamp(SimpleNamespace(clamping=True, limit_direct=limits[0],
                                                                     limit_indirect=limits[1]),
                                                     light, bounce[5:5 + m] == 0)
            assert not np.array_equal(expected[:, 5:5 + m], start[:, 5:5 + m] + light)
            radiance = start.copy()
            original(tracer, *args, **dict(kwargs, into=(radiance, beta, 5, bounce, limits)))
            assert np.array_equal(radiance, expected)
            radiance = start.copy()         # control: Clamp Direct up to bounce 1 (the emission's) differs
            original(tracer, *args, **dict(kwargs, into=(radiance, beta, 5, bounce - 1, limits)))
            assert not np.array_equal(radiance, expected)
    finally:
        session.PathTracer.lambert_direct_light = lambert
    assert len(fused) == 5 * min(len(calls), 6)        # the compiled case ran every time


def capture_scatters(scene, limit=6, **settings):
    """[(tracer, args)] deep copies of PathTracer.scatter's calls in a 16 x 16, 2 spp NumPy render of a built-in
    scene (by name) or a scene, with `settings`."""
    calls, reference = [], path_tracer.PathTracer.scatter
    scene = BUILTIN_SCENES[scene]((16, 16)) if isinstance(scene, str) else scene

    def recording(self, *args, **kwargs):
        if len(calls) < limit:
            calls.append((self, copy.deepcopy(args)))
        return reference(self, *args, **kwargs)
    path_tracer.PathTracer.scatter = recording
    try:
        api.render(scene, RenderSettings(**{"samples": 2, "threads": 1, "backend": "numpy", **settings}),
                   log=lambda m: None)
    finally:
        path_tracer.PathTracer.scatter = reference
    return calls


@pytest.mark.parametrize("scene", ["cornell", "caustic"])
def test_recorded_scatter_tails_in_the_compaction_are_bit_identical(scene, monkeypatch):
    """PathTracer.scatter on the compiled bounce and wavefront_jit.survivors with its tail against NumPy's scatter,
    roulette, np.flatnonzero and next_rays, on recorded scatters (made-up roulette numbers and origins);
    control: the tail's throughput one ulp off."""
    require_compiled()
    from engine.integrators import wavefront_jit
    tracers, init = [], path_tracer.PathTracer.__init__

    def keeping(self, *args, **kwargs):
        init(self, *args, **kwargs)
        tracers.append(self)
    monkeypatch.setattr(path_tracer.PathTracer, "__init__", keeping)
    calls = capture_scatters(scene)
    assert len(calls) >= 3 and tracers
    tracer, rng = tracers[0], np.random.default_rng(13)
    s = tracer.settings
    for _, args in calls:
        alive = len(args[2])
        u, offset, facing = rng.random(alive), 10.0 ** rng.uniform(-9, -3, alive), rng.normal(size=(3, alive))
        p, *rest = copy.deepcopy(args)
        tracer.wavefront_jit = None
        new_d, side, beta = tracer.scatter(p, *rest)
        keep, beta = tracer.roulette(beta, p.bounce[:alive], p.prev_delta[:alive], u)
        keep, ended = np.flatnonzero(keep), np.flatnonzero(~keep)
        expected = (keep, ended) + path_tracer.next_rays(keep, rest[0], side, offset, facing, new_d, beta) + (
            p.prev_delta, p.ray_kind)
        results = []
        for scale in (1.0, 1.0 + 2.0 ** -52):
            p, *rest = copy.deepcopy(args)
            tracer.wavefront_jit = wavefront_jit
            new_d, side, tail = tracer.scatter(p, *rest)
            assert side is None
            got = wavefront_jit.survivors(p.beta * scale, p.bounce[:alive], p.prev_delta[:alive], u, s.max_depth,
                                          tracer.final_rays, s.russian_roulette, s.rr_start_depth, rest[0], None,
                                          offset, facing, new_d, tail)
            results.append(tuple(got) + (p.prev_delta, p.ray_kind))
        assert len(keep) and same(expected, results[0]) and not same(expected, results[1])


def deferred_reference(tracer, args, u, offset, facing):
    """NumPy's lines of PathTracer.bounce with the deferred roulette on a recorded scatter call `args`: scatter,
    deferred_roulette, np.flatnonzero and next_rays; (keep, ended, o, d, beta, prev_delta, ray_kind, rr_after)."""
    p, *rest = copy.deepcopy(args)
    alive = len(rest[1])
    tracer.wavefront_jit = None
    new_d, side, beta = tracer.scatter(p, *rest)
    keep, p.rr_after[:alive] = tracer.deferred_roulette(beta, p.bounce[:alive], p.prev_delta[:alive], u)
    keep, ended = np.flatnonzero(keep), np.flatnonzero(~keep)
    return (keep, ended) + path_tracer.next_rays(keep, rest[0], side, offset, facing, new_d, beta) + (
        p.prev_delta, p.ray_kind, p.rr_after)


def deferred_compiled(tracer, args, u, offset, facing, scale=1.0, rr_start_depth=None):
    """The same through scatter on the compiled bounce and wavefront_jit.survivors with rr_after (the compiled bounce's
    call); scale: the throughput rows scaled, rr_start_depth: another one (controls)."""
    from engine.integrators import wavefront_jit
    p, *rest = copy.deepcopy(args)
    alive = len(rest[1])
    tracer.wavefront_jit = wavefront_jit
    s = tracer.settings
    new_d, side, tail = tracer.scatter(p, *rest)
    assert side is None
    got = wavefront_jit.survivors(p.beta * scale, p.bounce[:alive], p.prev_delta[:alive], u, s.max_depth,
                                  tracer.final_rays, s.russian_roulette, rr_start_depth or s.rr_start_depth, rest[0],
                                  None, offset, facing, new_d, tail, p.rr_after[:alive])
    return tuple(got) + (p.prev_delta, p.ray_kind, p.rr_after)


@pytest.mark.parametrize("rr_start_depth", [1, 3])
def test_recorded_deferred_roulettes_in_the_compaction_are_bit_identical(rr_start_depth):
    """The compiled bounce's pass with the deferred roulette (Cycles' order, scenes of Cycles' materials) against
    NumPy's lines, on the recorded scatters of a box with a Glossy wall (made-up roulette numbers and origins):
    the same kept and ended paths, next rays, flags and roulette factors (rr_after); controls: the throughput
    one ulp off, the roulette from one bounce later, and the plain roulette (no rr_after) differ."""
    require_compiled()
    from engine.integrators import wavefront_jit
    from tests.integrators.test_deferred_roulette import glossy_box
    calls = capture_scatters(glossy_box(), limit=8, rr_start_depth=rr_start_depth, max_depth=12)
    tracer, rng = calls[0][0], np.random.default_rng(17)
    assert len(calls) >= 4 and tracer.deferred_rr
    ended_some, controls = False, [False] * 3
    for _, args in calls:
        alive = len(args[2])
        u, offset, facing = rng.random(alive), 10.0 ** rng.uniform(-9, -3, alive), rng.normal(size=(3, alive))
        expected = deferred_reference(tracer, args, u, offset, facing)
        assert same(expected, deferred_compiled(tracer, args, u, offset, facing))
        ended_some |= bool((expected[-1][:alive] == 0.0).any() and (expected[-1][:alive] > 1.0).any())
        wrong = (deferred_compiled(tracer, args, u, offset, facing, scale=1.0 + 2.0 ** -52),
                 deferred_compiled(tracer, args, u, offset, facing, rr_start_depth=rr_start_depth + 1))
        controls[0] |= not same(expected, wrong[0])
        controls[1] |= not same(expected, wrong[1])
        p, *rest = copy.deepcopy(args)
        new_d, _, tail = tracer.scatter(p, *rest)
        s = tracer.settings
        plain = wavefront_jit.survivors(p.beta, p.bounce[:alive], p.prev_delta[:alive], u, s.max_depth,
                                        tracer.final_rays, True, rr_start_depth, rest[0], None, offset, facing, new_d,
                                        tail)
        controls[2] |= not same(expected[:5], plain)
    assert ended_some and all(controls), controls


def test_made_up_deferred_roulettes_with_nan_inf_and_signed_zeros():
    """wavefront_jit.survivors with rr_after against PathTracer.deferred_roulette, np.flatnonzero and
    path_tracer.next_rays on made-up paths (NaN, inf, -0, negative and tiny throughputs, u 0 and near 1,
    every bounce and delta flag, final rays on and off) and on no paths; controls: the throughput one ulp
    off and the roulette from one bounce later differ; an rr_after of another length or dtype is refused."""
    require_compiled()
    from engine.integrators import wavefront_jit
    rng = np.random.default_rng(23)
    n = 4000
    beta = rng.choice([0.0, -0.0, -0.5, 0.3, 1.0, 1.7, 4.0, np.nan, np.inf, -np.inf, 1e-300, 5e-324], (3, n))
    bounce, delta = rng.integers(0, 10, n).astype(np.int32), rng.random(n) < 0.5
    u = rng.choice([0.0, 0.25, 0.5, 1.0 - 2.0 ** -53, 0.7], n)
    point, facing, new_d = (rng.normal(0, 1e3, (3, n)) for _ in range(3))
    side, offset = np.where(rng.random(n) < 0.5, -1.0, 1.0), 10.0 ** rng.uniform(-12, 3, n)

    def compiled(m, final_rays, b=beta, start=3):
        after = np.full(m, -1.0)
        got = wavefront_jit.survivors(b[:, :m], bounce[:m], delta[:m], u[:m], 8, final_rays, True, start,
                                      point[:, :m], side[:m], offset[:m], facing[:, :m], new_d[:, :m],
                                      rr_after=after)
        return tuple(got) + (after,)
    for m in (n, 0):
        for final_rays in (False, True):
            tracer = SimpleNamespace(settings=SimpleNamespace(max_depth=8, rr_start_depth=3), final_rays=final_rays)
            with np.errstate(invalid="ignore"):
                keep, after = path_tracer.PathTracer.deferred_roulette(tracer, beta[:, :m], bounce[:m], delta[:m],
                                                                       u[:m])
            ended, keep = np.flatnonzero(~keep), np.flatnonzero(keep)
            expected = (keep, ended) + path_tracer.next_rays(keep, point[:, :m], side[:m], offset[:m], facing[:, :m],
                                                             new_d[:, :m], beta[:, :m]) + (after,)
            assert same(expected, compiled(m, final_rays))
            assert m == 0 or (0 < len(keep) < m and (after == 0.0).any() and (after > 1.0).any())
    assert not same(expected, compiled(n, True, b=beta * (1.0 + 2.0 ** -52)))
    assert not same(expected, compiled(n, True, start=4))
    for bad in (np.ones(n - 1), np.ones(n, np.float32), np.ones(2 * n)[::2]):
        with pytest.raises(ValueError):
            wavefront_jit.survivors(beta, bounce, delta, u, 8, True, True, 3, point, side, offset, facing, new_d,
                                    rr_after=bad)


def test_the_ray_kinds_are_the_path_tracers():
    require_compiled()
    from engine.integrators import wavefront_jit
    names = ("CAMERA_RAY", "DIFFUSE_RAY", "GLOSSY_RAY", "TRANSMISSION_RAY")
    assert [getattr(wavefront_jit, n) for n in names] == [getattr(path_tracer, n) for n in names]


def test_cosine_pdf_is_the_lambertians_pdf_of_the_cosine_the_kernel_has():
    """lambert_light computes a cosine_pdf BSDF's pdf as cos_x (1 / pi) (cos_x as light_tests sums
    it): the Lambertian's pdf gives those bits for random directions; control: a pdf an ulp off
    (what a BSDF wrongly marked cosine_pdf would give) does not."""
    from engine.materials.lambert import Lambertian
    from engine.materials.protocol import BSDF, ShadingPoint
    assert Lambertian.cosine_pdf and not BSDF.cosine_pdf
    rng = np.random.default_rng(3)
    n, w = rng.normal(size=(3, 500)), rng.normal(size=(3, 500))
    n, w = n / np.linalg.norm(n, axis=0), w / np.linalg.norm(w, axis=0)
    cos_x = n[0] * w[0] + n[1] * w[1] + n[2] * w[2]                 # _light_tests' sum
    si = ShadingPoint(n, n, n, n, np.ones((3, 500)), np.zeros(500, np.int64))
    kept = cos_x > 0.0
    pdf = Lambertian.__new__(Lambertian).pdf(si, w)
    assert np.array_equal(pdf[kept], cos_x[kept] * (1.0 / np.pi))
    assert not np.array_equal(np.nextafter(pdf, 1.0)[kept], cos_x[kept] * (1.0 / np.pi))


@pytest.mark.parametrize("scene,estimator,clamp", [("cornell", "mis", None), ("cornell", "report", None),
                                                   ("many_lights", "mis", None), ("near_lamp", "mis", None),
                                                   ("cornell", "mis", (1.0, 0.001)), ("many_lights", "mis", (1.0, 0.001))])
def test_recorded_emissions_are_bit_identical(scene, estimator, clamp, monkeypatch):
    """PathTracer.emission on deep copies of the calls of a real render, with NumPy's weights and sum and
    with this module's (emitter_lights, add_emission): the same radiance bit for bit, with Light Paths'
    clamp too; controls: a MIS weight or an emission 2^-40 off, every weight 1, or (clamp) no clamping or
    Clamp Direct for every bounce, differ."""
    require_compiled()
    from engine.integrators import wavefront_jit
    calls, original = [], path_tracer.PathTracer.emission

    def recording(self, *args):
        if len(calls) < 6:
            calls.append((self, copy.deepcopy(args)))
        return original(self, *args)
    monkeypatch.setattr(path_tracer.PathTracer, "emission", recording)
    clamps = {} if clamp is None else dict(clamp_direct=clamp[0], clamp_indirect=clamp[1])
    api.render(BUILTIN_SCENES[scene]((16, 16)), RenderSettings(samples=4, threads=1, backend="numpy",
                                                               estimator=estimator, **clamps), log=lambda m: None)
    monkeypatch.setattr(path_tracer.PathTracer, "emission", original)
    assert len(calls) >= 4 and (calls[0][0].clamp_limits == clamp)

    def radiance(tracer, args, jit):
        p, *rest = copy.deepcopy(args)
        tracer.wavefront_jit = jit
        original(tracer, p, *rest)
        return p.radiance

    def mis_off(radiance_, beta, idx, le, delta, pdf, places, p_light, mode, n, *rest):
        wavefront_jit.add_emission(radiance_, beta, idx, le, delta, pdf, places, p_light * (1.0 + 2.0 ** -40), mode, n,
                                   *rest)

    def le_off(radiance_, beta, idx, le, *rest):
        wavefront_jit.add_emission(radiance_, beta, idx, le * (1.0 + 2.0 ** -40), *rest)

    def weight_one(radiance_, beta, idx, le, delta, pdf, places, p_light, mode, n, *rest):
        wavefront_jit.add_emission(radiance_, beta, idx, le, delta, pdf, places, p_light, 0, n, *rest)

    def unclamped(*args):
        wavefront_jit.add_emission(*args[:-1], None)

    def all_direct(*args):
        wavefront_jit.add_emission(*args[:-2], np.zeros_like(args[-2]), args[-1])
    controls = [SimpleNamespace(emitter_lights=wavefront_jit.emitter_lights, add_emission=f)
                for f in (mis_off, le_off, weight_one, unclamped, all_direct)]
    differs = [False] * len(controls)
    for tracer, args in calls:
        reference, compiled = radiance(tracer, args, None), radiance(tracer, args, wavefront_jit)
        assert compiled.dtype == np.float64 and np.array_equal(reference, compiled, equal_nan=True)
        for k, control in enumerate(controls):
            differs[k] |= not np.array_equal(reference, radiance(tracer, args, control), equal_nan=True)
    assert differs[1] and differs[2] and (differs[0] or estimator != "mis")    # p_light is read under MIS only
    assert differs[3] == differs[4] == (clamp is not None)


def test_read_only_inputs_need_no_compilation_after_warm_up():
    """Callers hand the direct light read-only arrays (np.broadcast_to views: a light's normals) or
    writable ones: both must run warm_up's signatures (scripts/check_warm_up.py), with the same bits.
    Control: numba types a read-only array apart from a writable one (so a wrapper passing each
    as it comes would add a signature here)."""
    require_compiled()
    from engine.integrators import wavefront_jit as wj
    wj.warm_up()
    before = {k: len(k_.signatures) for k, k_ in (("t", wj._light_tests), ("l", wj._lambert_light))}
    rows = np.array([[0.0, 0.1, 0.3], [0.0, 0.2, -0.1], [1.0, 0.9, 0.8]])
    frozen = np.broadcast_to(np.array([[0.0], [0.0], [-1.0]]), (3, 3)).copy()
    frozen.flags.writeable = False
    p_b = np.full(3, 0.25)
    frozen_p_b = p_b.copy()
    frozen_p_b.flags.writeable = False
    results = []
    for normal, p_b in ((frozen.copy(), p_b), (frozen, frozen_p_b)):
        ls = SimpleNamespace(direction=rows, normal=normal, pdf=np.ones(3), distance=np.ones(3),
                             one_sided=np.ones(3, np.bool_), light=np.zeros(3, np.int64), radiance=rows)
        cos_x, cos_ly, valid = wj.light_tests(rows, ls, True)
        results.append((cos_x, cos_ly, valid, wj.lambert_light(valid, np.zeros(len(valid), np.bool_), cos_x, ls, p_b,
                                                               np.ones(1, np.bool_), True, rows)))
    assert len(results[0][2]) == 3 and all(np.array_equal(a, b) for a, b in zip(*results))
    assert {"t": len(wj._light_tests.signatures), "l": len(wj._lambert_light.signatures)} == before
    assert wj.nb.typeof(frozen) != wj.nb.typeof(frozen.copy())


def test_survivors_are_the_roulette_then_the_compaction():
    """wavefront_jit.survivors against PathTracer.roulette's NumPy lines, np.flatnonzero and
    path_tracer.next_rays on made-up paths (NaN, inf, -0 throughputs, both sides, every flag), with a
    control: the survival division one ulp off."""
    require_compiled()
    from engine.integrators import wavefront_jit
    rng = np.random.default_rng(11)
    n = 4000
    beta = rng.choice([0.0, -0.0, 0.3, 1.0, 1.7, np.nan, np.inf, 1e-300], (3, n))
    bounce, delta, u = rng.integers(0, 10, n).astype(np.int32), rng.random(n) < 0.5, rng.random(n)
    point, facing, new_d = (rng.normal(0, 1e3, (3, n)) for _ in range(3))
    side, offset = np.where(rng.random(n) < 0.5, -1.0, 1.0), 10.0 ** rng.uniform(-12, 3, n)
    for final_rays in (False, True):
        for rr in (False, True):
            settings = SimpleNamespace(max_depth=8, russian_roulette=rr, rr_start_depth=3)
            tracer = SimpleNamespace(settings=settings, final_rays=final_rays, wavefront_jit=None)
            keep, beta_rr = path_tracer.PathTracer.roulette(tracer, beta, bounce, delta, u)
            ended, keep = np.flatnonzero(~keep), np.flatnonzero(keep)
            expected = (keep, ended) + path_tracer.next_rays(keep, point, side, offset, facing, new_d, beta_rr)
            got = wavefront_jit.survivors(beta, bounce, delta, u, 8, final_rays, rr, 3, point, side, offset, facing,
                                          new_d)
            assert 0 < len(keep) < n and same(expected, got)
    wrong = wavefront_jit.survivors(beta * (1.0 + 2.0 ** -52), bounce, delta, u, 8, True, True, 3, point, side,
                                    offset, facing, new_d)
    assert same(expected[:2], wrong[:2]) and not same(expected, wrong)


def test_take_is_numpys_take():
    """wavefront_jit.take against ndarray.take for every dtype of the path state, on a sorting
    permutation and a compaction, with and without room after the taken paths (Paths.take's room), and
    None for what it does not compile (an axis-0 2-D array; every array for an int32 index); control:
    the index shifted by one gives other arrays."""
    require_compiled()
    from engine.integrators import wavefront_jit
    rng = np.random.default_rng(12)
    n = 3000
    arrays = [(rng.normal(size=(3, n)), 1), (rng.normal(size=n), 0), (rng.integers(0, 1 << 40, n), 0),
              (rng.integers(0, 9, n).astype(np.int32), 0), (rng.integers(-3, 4, n).astype(np.int8), 0),
              (rng.random(n) < 0.5, 0), (rng.integers(0, 9, (4, n)).astype(np.int32), 1)]
    for index in (np.argsort(rng.integers(0, 6, n), kind="stable"), np.flatnonzero(rng.random(n) < 0.7)):
        expected = [a.take(index, axis=axis) for a, axis in arrays]
        for room in (0, 17):
            got = wavefront_jit.take(arrays, index, room)
            assert [g.shape[-1] for g in got] == [len(index) + room] * len(arrays)
            assert same(expected, [g[..., :len(index)] for g in got])
        assert not same(expected[:6], wavefront_jit.take(arrays[:6], (index + 1) % n))
    assert wavefront_jit.take([(rng.normal(size=(n, 4)), 0)] + arrays[:1], np.arange(5))[0] is None
    assert wavefront_jit.take(arrays, np.arange(n - 5, dtype=np.int32)) == [None] * len(arrays)


# -- Light Paths' clamp and bounce limits, the background, the facing normals (branch glue4) --------------
def recorded_calls(owner, name, scene, limit=8, **settings):
    """[the arguments] of owner.name's first `limit` calls in a one-thread NumPy render: the first as it was
    (a method's tracer), deep copies of the others (the path state changes)."""
    calls, original = [], getattr(owner, name)

    def recording(first, *args):
        if len(calls) < limit:
            calls.append((first, *copy.deepcopy(args)))
        return original(first, *args)
    setattr(owner, name, recording)
    try:
        api.render(scene, RenderSettings(**{"samples": 4, "threads": 1, "backend": "numpy", **settings}),
                   log=lambda m: None)
    finally:
        setattr(owner, name, original)
    return calls


def sky_lit_box():
    """The built-in Cornell box without its lamp under a uniform sky, its only light (the world is then
    sampled as a light under `mis` and `solid-angle`): rays leave through its open front at every bounce."""
    scene = BUILTIN_SCENES["cornell"]((16, 16))
    for m in scene.materials:
        m.emission = (0.0, 0.0, 0.0)
    scene.background = (0.5, 0.6, 0.8)
    return scene


@pytest.mark.parametrize("estimator,clamp", [("mis", None), ("mis", (0.5, 0.05)), ("solid-angle", (0.5, 0.05)),
                                             ("report", None)])
def test_recorded_misses_are_bit_identical(estimator, clamp):
    """PathTracer.misses on the calls of a render of the Cornell box lit by a uniform sky through its open
    front (sky_lit_box): NumPy's
    weights (1, the delta flag, or MIS against the world's light samples), clamp and sum against this
    module's background_light, the same pixels and radiance bit for bit.  Controls: the world's pdf or the
    background 2^-40 off, no clamping, or Clamp Direct at every bounce, differ (those that apply)."""
    require_compiled()
    from engine.integrators import wavefront_jit
    clamps = {} if clamp is None else dict(clamp_direct=clamp[0], clamp_indirect=clamp[1])
    calls = recorded_calls(path_tracer.PathTracer, "misses", sky_lit_box(), estimator=estimator, max_depth=4, **clamps)
    assert len(calls) >= 4
    tracer = calls[0][0]
    assert tracer.world_nee == (estimator != "report") and tracer.clamp_limits == clamp

    def misses(args, jit):
        t, (p, miss, *rest) = args[0], copy.deepcopy(args[1:])
        t.wavefront_jit = jit
        return path_tracer.PathTracer.misses(t, p, miss, *rest)

    def changed(**change):
        def background_light(radiance, beta, idx, le, prev_delta, bsdf_pdf, places, p_light, mode, n_light, bounce,
                             clamp_):
            return wavefront_jit.background_light(
                radiance, beta, idx, le * change.get("le", 1.0), prev_delta, bsdf_pdf, places,
                p_light * change.get("p", 1.0), mode, n_light, np.zeros_like(bounce) if change.get("direct") else bounce,
                None if change.get("unclamped") else clamp_)
        return SimpleNamespace(sampled=wavefront_jit.sampled, background_light=background_light)
    controls = [changed(p=1.0 + 2.0 ** -40), changed(le=1.0 + 2.0 ** -40), changed(unclamped=True), changed(direct=True)]
    differs = [False] * len(controls)
    for args in calls:
        (pixel, reference), (pixel_c, compiled) = misses(args, None), misses(args, wavefront_jit)
        assert np.array_equal(pixel, pixel_c) and compiled.dtype == np.float64
        assert np.array_equal(reference, compiled, equal_nan=True)
        for k, control in enumerate(controls):
            differs[k] |= not np.array_equal(reference, misses(args, control)[1], equal_nan=True)
    assert differs == [estimator == "mis", True, clamp is not None, clamp is not None]


def test_made_up_background_light_with_nan_inf_and_signed_zeros():
    """background_light against the NumPy lines of PathTracer.misses (weights, power heuristic, clamp_contribution,
    the sum) on made-up paths: NaN and inf throughputs, zero and NaN pdfs, -0 radiance, a (3, 1) background;
    control: the power heuristic's light count 2 instead of 1 differs."""
    require_compiled()
    from engine.integrators import wavefront_jit
    from engine.integrators.light_paths import clamp_contribution
    rng = np.random.default_rng(21)
    n = 4000
    radiance, beta = rng.normal(size=(3, n)), rng.random((3, n)) * 4.0
    radiance[:, :50] = -0.0
    beta[0, 7], beta[1, 8], beta[2, 9] = np.nan, np.inf, -np.inf
    prev_delta = rng.random(n) < 0.3
    bsdf_pdf = rng.random(n)
    bsdf_pdf[11], bsdf_pdf[12], bsdf_pdf[13] = 0.0, np.nan, np.inf
    bounce = rng.integers(0, 5, n).astype(np.int32)
    miss = np.sort(rng.choice(n, 2500, replace=False))
    for le in (rng.random((3, 1)) * 3.0, rng.random((3, len(miss))) * 3.0):
        for mode in (0, 1, 2):
            for clamp in (None, (0.4, 0.1)):
                places = np.flatnonzero(~prev_delta.take(miss))
                p_world = rng.random(len(places)) * 2.0
                p_world[:3] = 0.0
                weight = np.ones(len(miss))
                if mode:
                    weight[places] = 0.0
                if mode == 2:
                    weight[places] = path_tracer.power_heuristic(1.0, bsdf_pdf.take(miss.take(places)), 1.0, p_world)
                with np.errstate(invalid="ignore"):         # (inf x 0 weights, inf x 0 scales: NaN)
                    contribution = beta.take(miss, axis=1) * le * weight
                    if clamp is not None:
                        contribution = clamp_contribution(contribution, np.where(bounce.take(miss) <= 1, *clamp))
                expected = radiance.take(miss, axis=1) + contribution
                got = wavefront_jit.background_light(radiance, beta, miss, le, prev_delta, bsdf_pdf, places, p_world, mode,
                                                     1, bounce, clamp)
                assert np.array_equal(expected, got, equal_nan=True)
                assert np.array_equal(np.signbit(expected), np.signbit(got))
                if mode == 2:
                    control = wavefront_jit.background_light(radiance, beta, miss, le, prev_delta, bsdf_pdf, places,
                                                             p_world, mode, 2, bounce, clamp)
                    assert not np.array_equal(expected, control, equal_nan=True)
    assert np.array_equal(wavefront_jit.sampled(miss, prev_delta), np.flatnonzero(~prev_delta.take(miss)))


def every_flag_combination(n, rng):
    from engine.materials.protocol import BSDFFlags
    return rng.integers(0, int(max(BSDFFlags)) * 2, n).astype(np.int8)


def test_bounce_counts_are_light_paths_counts():
    """count_bounces against LightPaths.count on every combination of lobe flags, and on the flags of a real
    render with bounce limits; control: the transparent bounces counted as transmissions differ."""
    require_compiled()
    from engine.integrators import wavefront_jit
    from engine.materials.protocol import BSDFFlags
    rng = np.random.default_rng(3)
    flags = every_flag_combination(3000, rng)
    recorded = recorded_calls(path_tracer.PathTracer, "scatter_light_paths", BUILTIN_SCENES["caustic"]((16, 16)),
                              diffuse_bounces=1, glossy_bounces=2)
    assert len(recorded) >= 4
    for f in [flags] + [args[3] for args in recorded]:
        counts = rng.integers(0, 5, (4, len(f) + 9)).astype(np.int32)
        expected, got = counts.copy(), counts.copy()
        LightPaths.count(None, expected[:, :len(f)], f)
        wavefront_jit.count_bounces(got, f)
        assert np.array_equal(expected, got)
    straight = (flags & BSDFFlags.STRAIGHT) != 0
    assert straight.any()
    control = counts[:, :0].copy()
    control = np.zeros((4, len(flags)), np.int32)
    wavefront_jit.count_bounces(control, np.where(straight, flags & ~np.int8(BSDFFlags.STRAIGHT), flags).astype(np.int8))
    expected = np.zeros((4, len(flags)), np.int32)
    LightPaths.count(None, expected, flags)
    assert not np.array_equal(expected, control)


@pytest.mark.parametrize("settings", [dict(diffuse_bounces=1, glossy_bounces=2), dict(max_depth=3)])
def test_recorded_final_groups_are_the_numpy_ones(settings):
    """PathTracer.final_groups compiled against NumPy's on the paths of a render (bounce limits, MIS final
    rays) and on made-up ones with the deferred roulette's ended paths (rr_after 0, NaN); control: final
    rays off gives other groups."""
    require_compiled()
    from engine.integrators import wavefront_jit
    calls = recorded_calls(path_tracer.PathTracer, "final_groups", BUILTIN_SCENES["caustic"]((16, 16)), **settings)
    assert len(calls) >= 4

    def groups(tracer, p, jit):
        tracer.wavefront_jit = jit
        return tracer.final_groups(p)
    found = False
    for tracer, p in calls:
        expected, got = groups(tracer, p, None), groups(tracer, p, wavefront_jit)
        assert (expected is None) == (got is None) and (got is None or np.array_equal(expected, got))
        found |= got is not None
    assert found
    rng = np.random.default_rng(8)
    tracer, p = calls[0]
    n = len(p.bounce)
    p.bounce = rng.integers(0, 10, n).astype(np.int32)
    if p.counts is not None:                # some past their limits, most not
        p.counts = np.where(rng.random((4, n)) < 0.05, 3, 0).astype(np.int32)
    p.rr_after = np.where(rng.random(n) < 0.1, 0.0, 1.5)
    p.rr_after[:3] = np.nan, -0.0, np.inf
    for final_rays in (True, False):
        tracer.final_rays = final_rays
        expected, got = groups(tracer, p, None), groups(tracer, p, wavefront_jit)
        assert np.array_equal(expected, got)
    assert not np.array_equal(got, wavefront_jit.final_groups(p.bounce, tracer.settings.max_depth, True, p.counts,
                                                              None if p.counts is None else tracer.light_paths.limits,
                                                              p.rr_after, path_tracer.ABSORB))


def test_recorded_facing_normals_are_the_numpy_ones(monkeypatch):
    """wavefront_jit.facing against path_tracer.facing_normals on the hits of a render with a smooth ball and
    on made-up rays with NaN, a ray along the surface (dot 0) and -0; control: turned by the shading
    normal's side instead differs."""
    require_compiled()
    from engine.integrators import wavefront_jit
    from tests.geometry.test_shading_normals import box_room
    calls = recorded_calls(path_tracer, "facing_normals", box_room(smooth_ball=True))
    assert len(calls) >= 4
    rng = np.random.default_rng(6)
    n = 500
    normal = rng.normal(size=(3, n))
    d, shading = rng.normal(size=(3, n)), normal + rng.normal(0, 0.3, (3, n))
    d[:, 0], normal[:, 1], shading[:, 2] = np.nan, -0.0, -0.0
    d[:, 3], normal[:, 3] = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)                   # along the surface: dot 0
    for args in calls + [(d, normal, shading)]:
        expected, got = path_tracer.facing_normals(*args), wavefront_jit.facing(*args)
        assert same(expected, got) and all(np.array_equal(np.signbit(a), np.signbit(b)) for a, b in zip(expected, got))
    wrong = path_tracer.facing_normals(d, shading, shading)[1]
    assert not same([wrong], [wavefront_jit.facing(d, normal, shading)[1]])


def test_one_bsdf_keeps_its_sample_arrays_and_other_arrays_are_copied():
    """path_tracer.filled: a BSDF's own C-contiguous array of the buffer's shape and dtype stands for the copy;
    anything else (a column slice, another dtype, a broadcast) is copied into the buffer, the same values."""
    rows = np.arange(12.0).reshape(3, 4)
    assert path_tracer.filled(np.empty((3, 4)), rows) is rows
    for a in (np.arange(15.0).reshape(3, 5)[:, :4], rows.astype(np.float32), np.ones(3)[:, None]):
        buffer = np.empty((3, 4))
        out = path_tracer.filled(buffer, a)
        assert out is buffer and np.array_equal(out, np.broadcast_to(a, (3, 4)))
    flags = np.full(4, 5, np.int64)
    assert path_tracer.filled(np.empty(4, np.int8), flags).dtype == np.int8
