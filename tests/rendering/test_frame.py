"""The frame side (engine/rendering/frame.py) over the tracer side (engine/rendering/session.py),
and the one film accumulator (engine/film/accumulator.py) that tiles, the frame and the viewport use."""
import pickle

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.film.accumulator import Film
from engine.pools.viewport import film_image, relative_error
from engine.rendering.frame import Frame
from engine.rendering.session import PreparedScene
from engine.rendering.units import make_tiles, make_units
from engine.scene.builtin import cornell_scene

QUIET = dict(log=lambda *a: None)


def test_a_frame_from_a_workers_facts_merges_its_units_into_the_render_image():
    """The frame side needs only the TracerFacts (as they come back pickled from a worker): the
    units a PreparedScene renders, merged in reverse order, are the image of render()."""
    scene, settings = cornell_scene((40, 24)), RenderSettings(samples=16, tile_size=16, seed=8)
    prepared = PreparedScene(scene, settings, **QUIET)
    facts = pickle.loads(pickle.dumps(prepared.facts()))
    frame = Frame(scene, settings, facts)
    assert not hasattr(frame, "geometry") and facts.accelerator == prepared.accelerator
    for unit in reversed(frame.units):
        frame.add(prepared.render_unit(unit))
    result = frame.result(1.0)
    assert np.array_equal(result.image, render(scene, settings, **QUIET).image)
    assert result.stats["accelerator_reason"] == prepared.accelerator_reason
    assert result.stats["effects"] == dict(prepared.plan.enabled)


def test_the_progressive_orders_are_tiles_and_frame():
    tiles = make_tiles(32, 32, 16)
    by_tile, by_frame = make_units(tiles, 2048, "tiles"), make_units(tiles, 2048, "frame")
    assert sorted((u.tile.index, u.chunk) for u in by_tile) == sorted((u.tile.index, u.chunk) for u in by_frame)
    assert [u.tile.index for u in by_frame[:len(tiles)]] == list(range(len(tiles)))
    assert [u.tile.index for u in by_tile[:2]] == [0, 0]
    with pytest.raises(ValueError, match="progressive order 'passes'"):
        make_units(tiles, 64, "passes")                    # the old name of "frame"


def test_the_growing_order_refines_the_whole_frame_in_doubling_chunks():
    """The viewport's order: chunk 0 of every tile is one sample, then 1, 2, 4, ... samples up to
    the size of the "frame" order's chunks; every sample of every tile once, in order."""
    tiles = make_tiles(32, 32, 16)                         # 256 pixels: "frame" chunks of 1024 samples
    growing, by_frame = make_units(tiles, 2048, "growing"), make_units(tiles, 2048, "frame")
    assert [u.tile.index for u in growing[:len(tiles)]] == list(range(len(tiles)))
    for tile in tiles:
        ranges = [(u.start, u.stop) for u in growing if u.tile == tile]
        assert ranges[:12] == [(0, 1), (1, 2), (2, 4), (4, 8), (8, 16), (16, 32), (32, 64), (64, 128),
                               (128, 256), (256, 512), (512, 1024), (1024, 2048)]
        assert [u.chunk for u in growing if u.tile == tile] == list(range(len(ranges)))
    assert max(u.stop - u.start for u in growing) == max(u.stop - u.start for u in by_frame)
    assert [(u.start, u.stop) for u in make_units(tiles, 5, "growing")[::len(tiles)]] == [(0, 1), (1, 2), (2, 4),
                                                                                            (4, 5)]


def test_the_film_variance_is_the_sample_variance_over_n():
    """Film.variance_of_mean against numpy's var(ddof=1) / n of the same samples; a variance with
    ddof=0 (the biased one) differs (control)."""
    rng = np.random.default_rng(3)
    film = Film(4, 3)
    pixel = rng.integers(0, 12, 5000)
    radiance = rng.gamma(2.0, 1.0, (3, 5000))
    film.add_samples(pixel, radiance)
    expected = np.zeros((12, 3))
    biased = np.zeros((12, 3))
    for p in range(12):
        x = radiance[:, pixel == p].T
        expected[p] = x.var(axis=0, ddof=1) / len(x)
        biased[p] = x.var(axis=0, ddof=0) / len(x)
    var = film.variance_of_mean().reshape(12, 3)
    np.testing.assert_allclose(var, expected, rtol=1e-5)
    assert not np.allclose(var, biased, rtol=1e-5)
    np.testing.assert_allclose(film.mean().reshape(12, 3),
                               [radiance[:, pixel == p].mean(axis=1) for p in range(12)], rtol=1e-6)


def test_the_viewport_film_is_the_film_of_its_frames():
    """The viewport's noise figure is the film's variance of the mean (one formula for both)."""
    rng = np.random.default_rng(4)
    film = Film(5, 4)
    for _ in range(6):
        s = rng.random((20, 3))
        film.add_sums(0, 0, s.reshape(4, 5, 3), (s * s).reshape(4, 5, 3), 1)
    mean = film.mean()
    expected = np.sqrt(film.variance_of_mean().mean()) / mean.mean()
    assert relative_error(film) == pytest.approx(expected, rel=1e-6)
    assert np.array_equal(film_image(film)[::-1, :, :3], mean)


def test_units_are_never_smaller_than_a_wavefront_where_the_tile_has_the_samples():
    """A unit smaller than the wavefront (engine/integrators/path_tracer.py WAVEFRONT_SIZE) pays
    the tail of few paths of a wavefront that never fills: every unit holds at least a wavefront of
    camera samples unless its tile's whole sample range is smaller (a tile's last chunk that small
    joins the one before).  Control: the viewport's growing chunks (1, 1, 2, 4 ... samples) are small
    on purpose."""
    from engine.integrators.path_tracer import WAVEFRONT_SIZE
    from engine.rendering.units import UNIT_PATHS
    assert UNIT_PATHS >= WAVEFRONT_SIZE
    for size, samples in ((64, 64), (64, 65), (64, 8), (256, 2), (16, 1100), (16, 1024), (8, 4100)):
        tiles = make_tiles(300, 200, size)
        units = make_units(tiles, samples)
        for unit in units:
            paths = unit.tile.pixels * (unit.stop - unit.start)
            assert paths >= min(WAVEFRONT_SIZE, unit.tile.pixels * samples), (size, samples, unit)
        assert [sum(u.stop - u.start for u in units if u.tile.index == t.index and u.part == 0)
                for t in tiles] == [samples] * len(tiles)
    assert min(u.stop - u.start for u in make_units(make_tiles(64, 64, 64), 64, "growing")) == 1
