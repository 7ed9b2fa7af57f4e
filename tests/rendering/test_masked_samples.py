"""engine/rendering/masked_samples.py: the masks adaptive sampling sends round-trip, and an active pixel's
camera samples are exactly the ones it gets in a full tile (adaptive sampling changes how many
samples a pixel gets, never which ones)."""
import numpy as np
import pytest

from engine.rendering.masked_samples import MaskedTileSamples, pack_mask, unpack_mask
from engine.sampling.qmc import SobolSampler
from engine.scene.camera_rays import TileSamples
from engine.scene.model import Camera

WIDTH, HEIGHT = 16, 12
TILE = (3, 2, 8, 5)                  # x0, y0, x1, y1: 5 x 3 pixels, not a multiple of 8
SPP = 6


@pytest.mark.parametrize("pixels", [1, 7, 8, 15, 64, 1000])
def test_pack_unpack_round_trip(pixels):
    rng = np.random.default_rng(pixels)
    for active in (rng.random(pixels) < 0.3, np.ones(pixels, bool), np.zeros(pixels, bool)):
        packed = pack_mask(active.reshape(1, -1))
        assert isinstance(packed, bytes) and len(packed) == (pixels + 7) // 8
        back = unpack_mask(packed, pixels)
        assert back.dtype == bool and back.shape == (pixels,)
        assert np.array_equal(back, active)


def test_pack_mask_takes_a_2d_tile_mask_row_by_row():
    active = np.array([[1, 0, 0], [0, 0, 1]], bool)
    assert np.array_equal(unpack_mask(pack_mask(active), 6), active.ravel())


def draw(samples, chunk):
    """{(pixel, sample): (origin, direction)} of every sample, taken in chunks of ``chunk``."""
    rays, order = {}, []
    while samples.remaining:
        pixel, sample, o, d = samples.take(chunk)
        for i, (p, s) in enumerate(zip(pixel.tolist(), sample.tolist())):
            assert (p, s) not in rays
            rays[p, s] = (o[:, i].copy(), d[:, i].copy())
            order.append(s)
    return rays, order


def camera_and_sampler():
    camera = Camera.look_at((0.3, -4, 1), (0, 0, 0.2), lens=35.0)
    x0, y0, x1, y1 = TILE
    return camera, SobolSampler(7, x0, y0, x1, y1, SPP, 1)


@pytest.mark.parametrize("first", [0, 2])
@pytest.mark.parametrize("as_indices", [False, True])
def test_masked_samples_are_the_full_tiles_samples_at_the_active_pixels(first, as_indices):
    camera, sampler = camera_and_sampler()
    x0, y0, x1, y1 = TILE
    pixels = (x1 - x0) * (y1 - y0)
    active = np.random.default_rng(3).random(pixels) < 0.4
    assert 0 < active.sum() < pixels
    full, _ = draw(TileSamples(camera, WIDTH, HEIGHT, *TILE, SPP, sampler, first=first), 11)
    masked_samples = MaskedTileSamples(camera, WIDTH, HEIGHT, *TILE, SPP, sampler,
                                       np.flatnonzero(active) if as_indices else active, first)
    assert masked_samples.total == active.sum() * (SPP - first)
    masked, order = draw(masked_samples, 4)
    assert set(masked) == {(p, s) for p in np.flatnonzero(active) for s in range(first, SPP)}
    for key, (o, d) in masked.items():
        assert np.array_equal(o, full[key][0]) and np.array_equal(d, full[key][1]), key
    assert order == sorted(order)                        # pass by pass, as the full tile
    assert masked_samples.remaining == 0 and len(masked_samples.take(5)[0]) == 0


def test_control_another_sampler_seed_gives_other_rays():
    """The comparison above can fail: a sampler with another seed moves the jittered rays."""
    camera, sampler = camera_and_sampler()
    other = SobolSampler(8, *TILE, SPP, 1)
    active = np.ones(15, bool)
    a, _ = draw(MaskedTileSamples(camera, WIDTH, HEIGHT, *TILE, SPP, sampler, active), 15)
    b, _ = draw(MaskedTileSamples(camera, WIDTH, HEIGHT, *TILE, SPP, other, active), 15)
    assert not any(np.array_equal(a[k][1], b[k][1]) for k in a)


def test_masked_samples_take_the_pixel_filter_as_the_full_tile():
    """With a pixel filter (engine/film/pixel_filter.py) an active pixel's rays are still the full
    tile's; and the filter moves them (a box of width 1 would not)."""
    from engine.film.pixel_filter import PixelFilter
    camera, sampler = camera_and_sampler()
    wide = PixelFilter("blackman-harris", 1.5)
    active = np.zeros(15, bool)
    active[[1, 7, 12]] = True
    full, _ = draw(TileSamples(camera, WIDTH, HEIGHT, *TILE, SPP, sampler, pixel_filter=wide), 7)
    masked, _ = draw(MaskedTileSamples(camera, WIDTH, HEIGHT, *TILE, SPP, sampler, active, pixel_filter=wide), 4)
    for key, (o, d) in masked.items():
        assert np.array_equal(d, full[key][1]), key
    plain, _ = draw(TileSamples(camera, WIDTH, HEIGHT, *TILE, SPP, sampler), 7)
    assert not any(np.array_equal(plain[k][1], full[k][1]) for k in masked)
