"""The compiled light samples of the lights at infinity against their NumPy path: SunLights.sample_li
through engine/sampling/warps_jit.py (uniform_cone with the axes read by index) and WorldLight.sample_li
through engine/materials/lambert_jit.py (cosine directions and cos / pi), both switched on by
LightSet's wavefront backend.  Bit for bit on the calls of real renders (a Cornell box lit by two
suns through its ceiling hole, and by a constant sky alone) and on hand-made inputs (NaN, inf, -0.0,
axes and normals with z = 0 and -0.0, uniforms at 0 and 1, a delta sun, no samples); a control shows
the comparison sees a last-bit change."""
import dataclasses

import numpy as np
import pytest

from engine import api
from engine.core.settings import RenderSettings
from engine.lights.distant import SunLights, WorldLight
from engine.scene.builtin import LIGHT, cornell_scene
from tests.backend_capture import require_compiled
from tests.lights.kinds import SUNS


def lit_by(what):
    """A 16 x 16 Cornell box lit by two suns through its ceiling hole ("suns"), or by a grey sky
    alone, its lamp off ("sky": the world is then sampled as a light)."""
    scene = cornell_scene((16, 16))
    if what == "suns":
        scene.suns = list(SUNS)
    else:
        scene.materials[LIGHT].emission = (0.0, 0.0, 0.0)
        scene.background = (0.5, 0.6, 0.7)
    return scene


def capture(kind, what, limit=8):
    """[(kind, args of sample_li)] of up to `limit` calls in a 2 spp NumPy render of lit_by(what)."""
    calls, original = [], kind.sample_li

    def recording(self, x, idx, u1, u2, n=None, solid_angle=True):
        if len(calls) < limit:
            calls.append((self, (x.copy(), np.array(idx).copy(), u1.copy(), u2.copy(), n.copy(), solid_angle)))
        return original(self, x, idx, u1, u2, n, solid_angle)
    kind.sample_li = recording
    try:
        api.render(lit_by(what), RenderSettings(samples=2, threads=1, backend="numpy"), log=lambda m: None)
    finally:
        kind.sample_li = original
    return calls


def both(light, args):
    """(NumPy's LiSample, the compiled one) of light.sample_li(*args)."""
    light.use_backend("numpy")
    reference = light.sample_li(*args)
    light.use_backend("numba")
    assert light.compiled.__name__ == {SunLights: "engine.sampling.warps_jit",
                                       WorldLight: "engine.materials.lambert_jit"}[type(light)]
    try:
        return reference, light.sample_li(*args)
    finally:
        light.use_backend("numpy")


def same(a, b) -> bool:
    """Two LiSamples the same bit for bit (zeros' signs and dtypes included)."""
    pairs = [(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a)]
    return all(np.asarray(x).dtype == np.asarray(y).dtype and np.array_equal(x, y, equal_nan=True)
               and np.array_equal(np.signbit(x), np.signbit(y)) for x, y in pairs)


@pytest.mark.parametrize("kind, what", [(SunLights, "suns"), (WorldLight, "sky")])
def test_recorded_samples_are_the_same(kind, what):
    require_compiled()
    calls = capture(kind, what)
    assert len(calls) >= 4
    for light, args in calls:
        assert same(*both(light, args))


def hand_made(m=300, seed=5):
    """Receivers, light numbers 0/1 and uniforms with the edge values; normals with z = 0 and -0.0,
    +-z, NaN and inf."""
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(3, m))
    n /= np.linalg.norm(n, axis=0)
    n[:, 0], n[:, 1], n[:, 2], n[:, 3] = (1.0, 0.0, 0.0), (0.0, 1.0, -0.0), (0.0, 0.0, 1.0), (0.0, 0.0, -1.0)
    n[:, 4], n[0, 5] = np.nan, np.inf
    n[2, 10:30], n[2, 30:40] = 0.0, -0.0
    u1, u2 = rng.random(m), rng.random(m)
    u1[40:45], u1[45:50], u2[50:55], u2[55:60] = 0.0, np.nextafter(1.0, 0.0), 0.0, np.nextafter(1.0, 0.0)
    u1[60:65] = 1.0
    u1[65], u2[66] = np.nan, np.nan
    x = rng.normal(size=(3, m))
    return x, rng.integers(0, 2, m), u1, u2, n


def test_hand_made_suns():
    """Both of kinds.SUNS (a delta sun: 1 - cos = 0, and a soft one), axes along x, y (z = 0 and
    -0.0) and -z added as suns of their own."""
    require_compiled()
    extra = [dataclasses.replace(SUNS[1], direction=d) for d in ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0))]
    suns = SunLights(list(SUNS) + extra, 3.0)
    suns.axis[2, 3] = -0.0                                   # the axis (-1, 0, -0.0)
    x, idx, u1, u2, n = hand_made()
    idx = idx + 3 * (np.arange(len(idx)) % 2)               # lights 0..4
    assert same(*both(suns, (x, idx, u1, u2, n)))
    empty = (np.zeros((3, 0)), np.zeros(0, np.int64), np.zeros(0), np.zeros(0), np.zeros((3, 0)))
    assert same(*both(suns, empty))


def test_hand_made_world():
    require_compiled()
    world = WorldLight((0.2, 0.3, 0.4), 3.0)
    x, idx, u1, u2, n = hand_made()
    assert same(*both(world, (x, np.zeros_like(idx), u1, u2, n)))
    wide = np.concatenate([n, n], axis=1)                    # a slice of the wavefront's rows, not a copy
    assert same(*both(world, (x, np.zeros_like(idx), u1, u2, wide[:, len(u1):])))


def test_control_a_last_bit_change_is_seen():
    """The comparison is exact: the compiled suns with one cone's 1 - cos a last bit wider give
    directions within 1e-12 of NumPy's, and `same` tells them apart."""
    require_compiled()
    light, args = capture(SunLights, "suns", limit=1)[0]
    reference, _ = both(light, args)
    light.use_backend("numba")
    kept = light.one_minus_cos.copy()
    light.one_minus_cos = np.nextafter(kept, 1.0)
    try:
        wrong = light.sample_li(*args)
    finally:
        light.one_minus_cos = kept
        light.use_backend("numpy")
    assert np.allclose(wrong.direction, reference.direction, rtol=0.0, atol=1e-12)
    assert not same(reference, wrong)
