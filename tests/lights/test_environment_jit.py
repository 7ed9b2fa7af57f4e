"""The image world's lookups on the numba backend (EnvironmentMap.use_backend: engine/materials/textures_jit.py's
twin of textures.lookup, the colour channels only) give NumPy's numbers bit for bit, for both projections and
interpolations, grey, RGB and RGBA images, 8-bit sRGB decoded after the lookup, a rotated world and directions
at the poles and the seam; with a control that a changed direction differs."""
import numpy as np
import pytest

from engine.lights.environment import EnvironmentMap
from engine.scene.model import Environment
from tests.backend_capture import require_compiled


def directions(rng, n=2000):
    d = rng.normal(size=(3, n))
    d[:, :4] = np.array([[0, 0, 1], [0, 0, -1], [-1, 0, 0], [-1, -0.0, 0]], float).T    # poles, the seam
    return d / np.sqrt((d * d).sum(axis=0))


@pytest.mark.parametrize("channels", [1, 3, 4])
@pytest.mark.parametrize("projection", ["equirectangular", "mirror_ball"])
@pytest.mark.parametrize("interpolation", ["Linear", "Closest"])
def test_compiled_lookups_are_numpys(channels, projection, interpolation):
    require_compiled()
    rng = np.random.default_rng(channels)
    pixels = rng.random((16, 32, channels)).astype(np.float32) * 4.0
    matrix = ((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)) if channels == 3 else Environment(0).matrix
    for decode_after in (False, True):
        env = EnvironmentMap(Environment(0, projection=projection, interpolation=interpolation, matrix=matrix),
                             pixels, decode_after)
        d = directions(rng)
        env.use_backend("numpy")
        expected = env.radiance(d)
        env.use_backend("numba")
        assert env.compiled is not None
        got = env.radiance(d)
        assert np.array_equal(got, expected)
        assert not np.array_equal(env.radiance(np.roll(d, 1, axis=1)), expected)          # control
        env.use_backend("numpy")
        assert env.compiled is None


@pytest.mark.filterwarnings("ignore:invalid value encountered in cast")        # NaN coordinates' casts
def test_compiled_sampler_is_numpys():
    """PiecewiseConstant2D.sample and pdf (engine/lights/environment_jit.py): zero rows and columns (the
    searches' ties), uniforms at 0 and just below 1, NaN, coordinates outside [0, 1)."""
    require_compiled()
    from engine.lights import environment_jit
    from engine.lights.environment import PiecewiseConstant2D
    rng = np.random.default_rng(5)
    weights = rng.random((24, 40)) ** 4
    weights[3], weights[:, 7], weights[-2:] = 0.0, 0.0, 0.0          # zero rows (the last ones too), a zero column
    dist = PiecewiseConstant2D(weights)
    u1, u2 = rng.random(5000), rng.random(5000)
    u1[:4], u2[:4] = [0.0, np.nextafter(1.0, 0.0), np.nan, 0.5], [0.0, np.nextafter(1.0, 0.0), 0.5, np.nan]
    expected = dist.sample(u1, u2)
    u, v = rng.random(3000) * 1.4 - 0.2, rng.random(3000) * 1.4 - 0.2
    u[:2], v[2:4] = np.nan, np.nan
    expected_pdf = dist.pdf(u, v)
    dist.jit = environment_jit
    for a, b in zip(dist.sample(u1, u2), expected):
        assert np.array_equal(a, b, equal_nan=True)
    assert np.array_equal(dist.pdf(u, v), expected_pdf)
    assert not np.array_equal(dist.sample(np.nextafter(u1, 1.0), u2)[0], expected[0], equal_nan=True)   # control
    assert not np.array_equal(dist.pdf(u, np.roll(v, 1)), expected_pdf)                                  # control
