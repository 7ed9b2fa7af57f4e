"""The compiled shadow rays (engine/lights/light_set_jit.py) and parallelogram samples and densities
(engine/lights/parallelograms_jit.py `sample_li`, `pdf_li`) against the NumPy path of engine/lights/light_set.py
and parallelograms.py, on inputs recorded from a render of the built-in Cornell box
(tests/backend_capture.py) and on the hard cases: lights at infinity, the shadow-terminator
lift, subsets of the samples; a control that moves one input by an ulp must differ."""
import numpy as np
import pytest

from engine.lights.light_set import LightSample
from tests.backend_capture import capture, require_compiled

TWIN = "engine.lights.light_set_jit"          # imported after require_compiled(): numba may be missing


@pytest.fixture(scope="module")
def calls():
    require_compiled()
    return capture("cornell")


def _same(a, b):
    return all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))


def _numpy_and_compiled(light_set, args):
    from engine.lights import light_set_jit
    saved = light_set.compiled_shadows
    light_set.compiled_shadows = None
    try:
        reference = light_set.shadow_rays(*args)
    finally:
        light_set.compiled_shadows = saved
    return reference, light_set_jit.shadow_rays(*args)


def test_captured_shadow_rays_are_bit_identical(calls):
    assert len(calls["shadow"]) >= 8
    for light_set, args in calls["shadow"]:
        reference, compiled = _numpy_and_compiled(light_set, args)
        assert _same(reference, compiled)


def test_captured_rectangle_samples_are_bit_identical(calls):
    assert calls["rectangle"]
    for lights, x, idx, u1, u2 in calls["rectangle"]:
        assert lights.compiled is None
        a = lights.sample_li(x, idx, u1, u2)
        lights.use_backend("numba")
        try:
            b = lights.sample_li(x, idx, u1, u2)
            pdf_b = lights.pdf_li(x, idx, a.point)
        finally:
            lights.use_backend("numpy")
        for name in ("point", "direction", "distance", "normal", "radiance", "pdf"):
            assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name
        assert np.array_equal(lights.pdf_li(x, idx, a.point), pdf_b)


def _random_samples(rng, k):
    point = rng.normal(size=(3, k)) * 3.0
    normal = rng.normal(size=(3, k))
    normal /= np.linalg.norm(normal, axis=0)
    distance = rng.random(k) * 4.0
    distance[::5] = np.inf                                       # lights at infinity
    direction = rng.normal(size=(3, k))
    direction /= np.linalg.norm(direction, axis=0)
    return LightSample(point, direction, distance, normal, np.ones((3, k)), rng.random(k), np.zeros(k, np.int64),
                       2.0 ** -20 * np.abs(point).max(axis=0), np.zeros(k, bool))


def test_hard_cases_and_control():
    require_compiled()
    from engine.lights.light_set import LightSet
    from engine.scene.builtin import BUILTIN_SCENES
    light_set = LightSet(BUILTIN_SCENES["cornell"]((8, 8)), shapes_backend="numba")
    rng = np.random.default_rng(7)
    k = 2000
    ls = _random_samples(rng, k)
    x, ng = rng.normal(size=(3, k)), rng.normal(size=(3, k))
    lift = rng.random(k) * 1e-4 * np.where(rng.random(k) < 0.3, -1.0, 1.0)       # the far side too
    cos_ly = rng.normal(size=k)
    cos_ly[:7] = 0.0
    valid = np.flatnonzero(rng.random(k) < 0.7)
    raised = (rng.random(k) * np.where(rng.random(k) < 0.5, 0.0, 1.0), rng.normal(size=(3, k)))
    for args in [(ls, None, x, lift, ng, cos_ly), (ls, valid, x, lift, ng, cos_ly),
                 (ls, valid, x, lift, ng, cos_ly, raised), (ls, valid[:1], x, np.zeros(k), ng, cos_ly)]:
        reference, compiled = _numpy_and_compiled(light_set, args)
        assert _same(reference, compiled)
    # Control: one receiver moved by an ulp is seen.
    moved = x.copy()
    moved[0, valid[1]] = np.nextafter(moved[0, valid[1]], 9.0)
    reference, _ = _numpy_and_compiled(light_set, (ls, valid, x, lift, ng, cos_ly))
    _, compiled = _numpy_and_compiled(light_set, (ls, valid, moved, lift, ng, cos_ly))
    assert not _same(reference, compiled)


def test_light_set_samples_are_bit_identical():
    """LightSet.sample with the compiled rectangles and tail (finish_sample) against NumPy's, for one
    rectangle lamp (the Cornell box) and many lamps (the many-lights room, its light tree)."""
    require_compiled()
    from engine.lights.light_set import LightSet
    from engine.scene.builtin import BUILTIN_SCENES
    rng = np.random.default_rng(11)
    k = 3000
    for name in ("cornell", "many_lights"):
        scene = BUILTIN_SCENES[name]((8, 8))
        a, b = LightSet(scene), LightSet(scene, backend="numba", shapes_backend="numba")
        x = rng.normal(size=(3, k)) * 0.5 + np.array([[0.0], [0.0], [0.5]])
        n = rng.normal(size=(3, k))
        n /= np.linalg.norm(n, axis=0)
        u = rng.random((3, k))
        sa, sb = a.sample(x, n, *u), b.sample(x, n, *u)
        for field in sa.__dataclass_fields__:
            assert np.array_equal(getattr(sa, field), getattr(sb, field), equal_nan=True), (name, field)
    # Control: the tail sees a pmf off by an ulp and a NaN point.
    from engine.lights import light_set_jit
    point = rng.normal(size=(3, 4))
    point[1, 2] = np.nan
    pmf = np.full(4, 0.5)
    pdf, offset, _ = light_set_jit.finish_sample(np.ones(4), pmf, 0.9, point, np.zeros(4, np.int64),
                                                 np.zeros(1, bool), 2.0 ** -20)
    assert np.isnan(offset[2]) and np.array_equal(offset[[0, 1, 3]], (2.0 ** -20 * np.abs(point).max(axis=0))[[0, 1, 3]])
    assert not np.array_equal(pdf, light_set_jit.finish_sample(np.ones(4), np.nextafter(pmf, 1.0), 0.9, point,
                                                               np.zeros(4, np.int64), np.zeros(1, bool), 1.0)[0])


def test_samples_of_lights_at_infinity_are_bit_identical():
    """LightSet.sample on the wavefront's backend (the suns' and the world's compiled samples, the tail in
    finish_sample when every ray picks one group) against NumPy's: the Cornell box with two suns (both
    groups; then every ray picking the suns, then every ray the lamp), two suns alone, a grey sky alone.
    Control: the compiled set with one sun's cone a last bit wider differs."""
    require_compiled()
    from engine.lights.light_set import LightSet
    from engine.scene.builtin import BUILTIN_SCENES, LIGHT
    from tests.lights.kinds import SUNS
    rng = np.random.default_rng(12)
    k = 2000
    x = rng.normal(size=(3, k)) * 0.5 + np.array([[0.0], [0.0], [0.5]])
    n = rng.normal(size=(3, k))
    n /= np.linalg.norm(n, axis=0)
    n[2, :5] = -0.0
    u = rng.random((3, k))
    with_suns, suns_alone, sky = (BUILTIN_SCENES["cornell"]((8, 8)) for _ in range(3))
    for scene in (with_suns, suns_alone):
        scene.suns = list(SUNS)
    for scene in (suns_alone, sky):
        scene.materials[LIGHT].emission = (0.0, 0.0, 0.0)
    sky.background = (0.5, 0.6, 0.7)
    compiled = {"backend": "numba", "shapes_backend": "numba", "wavefront_backend": "numba"}
    for scene, world in ((with_suns, False), (suns_alone, False), (sky, True)):
        a, b = LightSet(scene, world=world), LightSet(scene, world=world, **compiled)
        q = a.distant_share
        assert q > 0
        for picks in (u[0], u[0] * q, q + (1.0 - q) * u[0]) if q < 1.0 else (u[0],):
            sa, sb = a.sample(x, n, picks, u[1], u[2]), b.sample(x, n, picks, u[1], u[2])
            for field in sa.__dataclass_fields__:
                assert np.array_equal(getattr(sa, field), getattr(sb, field), equal_nan=True), (scene.name, field)
    sun = LightSet(suns_alone, **compiled)
    reference = LightSet(suns_alone).sample(x, n, *u)
    sun.distant.kinds[0].one_minus_cos = np.nextafter(sun.distant.kinds[0].one_minus_cos, 1.0)
    assert not np.array_equal(sun.sample(x, n, *u).direction, reference.direction)


def test_read_only_inputs_need_no_compilation_after_warm_up():
    """Shadow rays from read-only arrays (np.broadcast_to views, as engine/lights/parallelograms.py's
    light normals) run warm_up's signature with the writable arrays' bits (scripts/check_warm_up.py);
    control: numba types a read-only array apart from a writable one."""
    require_compiled()
    from types import SimpleNamespace
    from engine.lights import light_set_jit as lj
    lj.warm_up()
    count = len(lj._shadow_rays.signatures)
    x = np.array([[0.0, 1.0], [0.0, 0.5], [0.0, 0.0]])
    normal = np.broadcast_to(np.array([[0.0], [0.0], [-1.0]]), (3, 2))
    out = []
    for n in (normal.copy(), normal):
        ls = SimpleNamespace(offset=np.full(2, 1e-6), point=x + 2.0, normal=n, distance=np.array([1.0, np.inf]),
                             direction=np.ones((3, 2)))
        out.append(lj.shadow_rays(ls, None, x, np.broadcast_to(1e-4, (2,)), x[::-1].copy(), np.ones(2)))
    assert _same(*out) and len(lj._shadow_rays.signatures) == count
    assert lj.nb.typeof(normal) != lj.nb.typeof(normal.copy())
