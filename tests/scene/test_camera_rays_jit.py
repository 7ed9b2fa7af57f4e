"""The compiled primary rays (engine/scene/camera_rays_jit.py) against engine/scene/camera_rays.py
TileSamples: the built-in scenes' cameras and made-up ones (each sensor fit, shifts, a scaled and
rotated matrix), tiles away from the corner, pixel filters (Gaussian, Blackman-Harris, a wide box) and
masked samples; the filter's table read as np.interp reads it (filter_offset)."""
import numpy as np
import pytest

from engine.film.pixel_filter import PixelFilter
from engine.rendering.masked_samples import MaskedTileSamples
from engine.sampling.qmc import SobolSampler
from engine.scene.builtin import BUILTIN_SCENES
from engine.scene.camera_rays import TileSamples
from engine.scene.model import Camera
from tests.backend_capture import require_compiled

TWIN = "engine.scene.camera_rays_jit"       # imported after require_compiled(): numba may be missing


def cameras():
    out = [BUILTIN_SCENES[name]((8, 8)).camera for name in sorted(BUILTIN_SCENES)]
    for fit, shift in (("AUTO", (0.1, -0.2)), ("HORIZONTAL", (0.0, 0.3)), ("VERTICAL", (-0.25, 0.0))):
        camera = Camera.look_at((3.0, -7.0, 2.5), (0.2, 0.1, 0.9), lens=35.0, sensor_fit=fit, sensor_width=32.0,
                                sensor_height=20.0, shift_x=shift[0], shift_y=shift[1])
        camera.matrix[:3, :3] *= np.array([1.5, 0.7, 2.0])           # an object scale (dropped)
        out.append(camera)
    return out


def tiles(compiled, camera, pixel_filter=None, masked=False):
    """Every ray of two tiles' samples 3 .. 8 (a 200 x 120 frame), with or without the twin."""
    out = []
    for x0, y0, x1, y1 in ((0, 0, 64, 64), (128, 64, 200, 120)):
        sampler = SobolSampler(5, x0, y0, x1, y1, 8, 1)
        if masked:
            active = (np.arange((x1 - x0) * (y1 - y0)) % 3) == 1
            samples = MaskedTileSamples(camera, 200, 120, x0, y0, x1, y1, 8, sampler, active, 3, pixel_filter)
        else:
            samples = TileSamples(camera, 200, 120, x0, y0, x1, y1, 8, sampler, 3, pixel_filter)
        samples.compiled = compiled
        while samples.remaining:
            out.append(samples.take(5000))
    return out


def same(a, b):
    return len(a) == len(b) and all(x.dtype == y.dtype and np.array_equal(x, y) for s, t in zip(a, b)
                                    for x, y in zip(s, t))


@pytest.mark.parametrize("pixel_filter, masked", [(None, False), (PixelFilter("gaussian", 1.5), False),
                                                  (None, True), (PixelFilter("blackman-harris", 1.5), True),
                                                  (PixelFilter("box", 2.0), False)])
def test_rays_are_bit_identical(pixel_filter, masked):
    require_compiled()
    from engine.scene import camera_rays_jit
    for camera in cameras():
        reference = tiles(None, camera, pixel_filter, masked)
        assert same(reference, tiles(camera_rays_jit, camera, pixel_filter, masked))
    # Control: a camera whose lens is one ulp longer gives other directions.
    other = cameras()[-1]
    other.lens = np.nextafter(other.lens, np.inf)
    assert not same(reference, tiles(camera_rays_jit, other, pixel_filter, masked))


def filter_inputs(uniform):
    """Filter numbers u: every knot of the table (u = j / 1022 and its neighbours), both ends, 0, the
    largest u below 1, values outside [0, 1] (clipped), `uniform` random ones and the jitters of a
    real tile (the Sobol' sampler's dimension pair 0, as TileSamples takes them)."""
    knots = np.arange(1023) / 1022.0
    assert np.array_equal(knots * 1022.0, np.arange(1023))      # the knots are hit exactly: x = 0 .. 1022
    sampler = SobolSampler(5, 0, 0, 32, 32, 16, 1)
    jitter = sampler.pair(np.tile(np.arange(32 * 32), 16), np.repeat(np.arange(16), 32 * 32), 0)
    return np.concatenate([knots, np.nextafter(knots, -1.0), np.nextafter(knots, 2.0),
                           [0.0, -0.0, 1.0 - 2.0 ** -53, 1.0, -1e-300, -0.5, 1.0 + 2.0 ** -52, 7.0],
                           np.random.default_rng(26).random(uniform), *jitter])


@pytest.mark.parametrize("pixel_filter, uniform", [(PixelFilter("blackman-harris", 1.5), 10 ** 6),
                                                   (PixelFilter("gaussian", 1.5), 10 ** 4),
                                                   (PixelFilter("blackman-harris", 0.7), 10 ** 4)])
def test_filter_offsets_are_bit_identical(pixel_filter, uniform):
    require_compiled()
    from engine.scene.camera_rays_jit import filter_offset, filter_offsets
    u = filter_inputs(uniform)
    reference = pixel_filter.offsets(u)
    assert np.array_equal(reference, filter_offsets(u, pixel_filter.table))
    assert np.array_equal(reference[:5000], [filter_offset(v, pixel_filter.table) for v in u[:5000]])
    # Control: the same interpolation as a lerp, (1 - t) a + t b, is off by an ulp here and there.
    table, x = pixel_filter.table, np.clip(u, 0.0, 1.0) * 1022.0
    j = np.minimum(x.astype(np.int64), 1021)
    lerp = (1.0 - (x - j)) * table[j] + (x - j) * table[j + 1]
    assert not np.array_equal(reference, lerp)
    assert np.max(np.abs(reference - lerp)) < 1e-15          # offsets are below 2.5: a few ulps
