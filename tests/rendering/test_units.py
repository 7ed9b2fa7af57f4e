"""The work units' balance (engine/rendering/units.py balance_units): a frame of few units splits its
last units in bands of rows, which keeps every pixel's sample ranges, so the image stays the same bit
for bit; frames already balanced keep their units."""
import numpy as np

from engine import RenderSettings
from engine.rendering.frame import Frame
from engine.rendering.session import PreparedScene
from engine.rendering import units as units_module
from engine.rendering.units import (UNIT_PATHS, WorkUnit, make_tiles, make_units, makespan, split_rows,
                                    tile_size_for)
from engine.scene.builtin import cornell_scene

QUIET = dict(log=lambda *a: None)


def frame_units(width, height, samples, balance=True, order="tiles"):
    return make_units(make_tiles(width, height, tile_size_for(width, height, 64)), samples, order, balance=balance)


def pixel_ranges(units, width, height):
    """(H, W, chunks, 2): each pixel's sample ranges in the order the frame merges them (chunk
    order), -1 past its last; every pixel covered by exactly one unit of each of its chunks."""
    most = max(u.chunk for u in units) + 1
    ranges = np.full((height, width, most, 2), -1)
    for u in units:
        region = ranges[u.tile.y0:u.tile.y1, u.tile.x0:u.tile.x1, u.chunk]
        assert (region == -1).all(), u
        region[:] = (u.start, u.stop)
    assert (ranges[:, :, 0] >= 0).all()
    return ranges


def split_samples(unit):
    """A wrong balance (the control): the unit's sample range in two halves."""
    mid = (unit.start + unit.stop) // 2
    return [WorkUnit(unit.index, unit.tile, unit.chunk, unit.start, mid),
            WorkUnit(unit.index, unit.tile, unit.chunk + 1, mid, unit.stop)]


def test_a_frame_of_nine_units_splits_its_last_in_two_bands_that_keep_every_pixels_samples():
    """96x96 at 256 spp: 9 units of 2^18 paths (5 rounds on 2 workers, one idle in the last) become 8
    and two bands of the last tile's rows, 2^17 paths each; every pixel keeps its sample ranges.
    Control: halving the last unit's samples instead changes the ranges of its pixels."""
    plain, balanced = frame_units(96, 96, 256, balance=False), frame_units(96, 96, 256)
    assert len(plain) == 9 and len(balanced) == 10
    assert [u.paths for u in balanced] == [UNIT_PATHS] * 8 + [UNIT_PATHS // 2] * 2
    assert [(u.part, u.parts) for u in balanced[-2:]] == [(0, 2), (1, 2)]
    assert [u.index for u in balanced] == list(range(10))
    assert np.array_equal(pixel_ranges(balanced, 96, 96), pixel_ranges(plain, 96, 96))
    wrong = plain[:-1] + split_samples(plain[-1])
    assert not np.array_equal(pixel_ranges(wrong, 96, 96), pixel_ranges(plain, 96, 96))
    paths = lambda units: [u.paths + units_module.TAIL_PATHS for u in units]
    for workers in (2, 4):
        assert makespan(paths(balanced), workers) < makespan(paths(plain), workers)


def test_frames_already_balanced_or_of_small_units_keep_their_units_exactly():
    """128x128 at 16 spp (the animation benchmark: 4 units of 2^16 paths), 300x200 at 64 spp and
    1920x1080 at 128 spp: nothing to split.  Control: 96x96 at 256 spp splits."""
    for width, height, samples in ((128, 128, 16), (300, 200, 64), (1920, 1080, 128), (96, 96, 16)):
        assert frame_units(width, height, samples) == frame_units(width, height, samples, balance=False)
    assert frame_units(96, 96, 256) != frame_units(96, 96, 256, balance=False)


def test_balance_keeps_every_pixels_sample_ranges_wherever_it_splits():
    """Over sizes, samples and both orders; the growing order (the viewport) is never balanced."""
    for width, height in ((96, 96), (100, 100), (128, 128), (256, 256), (100, 40)):
        for samples in (64, 256, 300, 1024):
            for order in ("tiles", "frame"):
                plain, balanced = (frame_units(width, height, samples, b, order) for b in (False, True))
                assert np.array_equal(pixel_ranges(balanced, width, height), pixel_ranges(plain, width, height))
                assert min(u.paths for u in balanced) >= min(min(u.paths for u in plain), UNIT_PATHS // 2)
                assert len(balanced) - len(plain) <= units_module.MOST_BALANCE_SPLITS
    assert frame_units(96, 96, 256, order="growing") == frame_units(96, 96, 256, False, "growing")


def test_split_rows_halves_the_tiles_rows():
    unit = frame_units(96, 96, 256, balance=False)[-1]
    top, bottom = split_rows(unit)
    assert (top.tile.y0, top.tile.y1, bottom.tile.y0, bottom.tile.y1) == (64, 80, 80, 96)
    assert top.tile.index == bottom.tile.index == unit.tile.index
    assert (top.start, top.stop) == (bottom.start, bottom.stop) == (unit.start, unit.stop)


def test_a_render_of_split_units_has_the_same_film_bit_for_bit(monkeypatch):
    """With units of 2^10 paths (tails of 32), a 12x12 Cornell box at 64 spp (9 units, as 96x96 at
    256 spp) splits its last unit in bands; its float32 image and float64 sums equal those of the
    frame without balance, with the units merged in reverse order (the frame merges the bands of a
    chunk after the tile's chunk before).  Control: with the random sampler the bands draw their own
    numbers, and the image differs."""
    monkeypatch.setattr(units_module, "UNIT_PATHS", 1 << 10)
    monkeypatch.setattr(units_module, "TAIL_PATHS", 32)
    scene, original = cornell_scene((12, 12)), units_module.make_units
    results = {}
    for sampler in ("sobol", "random"):
        settings = RenderSettings(samples=64, tile_size=8, seed=3, sampler=sampler, threads=1)
        prepared = PreparedScene(scene, settings, **QUIET)
        for balance in (False, True):
            monkeypatch.setattr("engine.rendering.frame.make_units",
                                lambda *a, balance=balance, **k: original(*a, **{**k, "balance": balance,
                                                                                 "workers": None}))
            frame = Frame(scene, settings, prepared.facts())
            for unit in reversed(frame.units):
                frame.add(prepared.render_unit(unit))
            results[sampler, balance] = frame.result(1.0)
    assert results["sobol", True].stats["units"] == results["sobol", False].stats["units"] + 1 == 10
    a, b = results["sobol", False], results["sobol", True]
    assert np.array_equal(a.image, b.image)
    for name in ("sum", "sum_sq", "count"):
        assert np.array_equal(getattr(a.film, name), getattr(b.film, name))
    assert not np.array_equal(results["random", False].image, results["random", True].image)


def test_a_band_travels_to_dask_workers_whole():
    """A Dask task carries a unit as plain values (engine/pools/dask_cluster.py plain_unit): a band's
    part and parts with it.  Control: a unit of the whole tile is another unit."""
    from engine.pools.dask_cluster import plain_unit, unit_from_plain
    band = frame_units(96, 96, 256)[-1]
    assert band.parts == 2 and unit_from_plain(plain_unit(band)) == band
    whole = frame_units(96, 96, 256, balance=False)[-1]
    assert unit_from_plain(plain_unit(whole)) == whole != band


def test_a_sobol_frame_is_balanced_for_its_worker_count_keeping_every_pixels_samples():
    """The Sobol' sampler's numbers depend on the pixel and sample only, so the frame balances its units
    for the render's threads (engine/rendering/frame.py): 96x96 at 64 spp on 2 workers splits the
    32x32 corner tile (makespan 1.19 -> 1.08 of the even share with tails), every pixel keeping its
    sample ranges.  Control: the random sampler keeps the units of every worker count."""
    plain = frame_units(96, 96, 64, balance=False)
    tiles = make_tiles(96, 96, tile_size_for(96, 96, 64))
    for_two = make_units(tiles, 64, workers=2)
    assert np.array_equal(pixel_ranges(for_two, 96, 96), pixel_ranges(plain, 96, 96))
    paths = lambda units: [u.paths + units_module.TAIL_PATHS for u in units]
    assert makespan(paths(for_two), 2) < makespan(paths(frame_units(96, 96, 64)), 2)
    assert [(u.tile.index, u.parts) for u in for_two] == [(0, 1), (1, 1), (2, 1), (3, 2), (3, 2)]
    scene = cornell_scene((96, 96))
    prepared = PreparedScene(scene, RenderSettings(samples=1, threads=1), **QUIET)
    for sampler, expected in (("sobol", for_two), ("random", frame_units(96, 96, 64))):
        frame = Frame(scene, RenderSettings(samples=64, threads=2, sampler=sampler), prepared.facts())
        assert frame.units == expected
    for width, height, samples in ((100, 40, 300), (256, 256, 16), (128, 128, 64)):
        plain = frame_units(width, height, samples, balance=False)
        for workers in (1, 2, 3, 8):
            tiles = make_tiles(width, height, tile_size_for(width, height, 64))
            balanced = make_units(tiles, samples, workers=workers)
            assert np.array_equal(pixel_ranges(balanced, width, height), pixel_ranges(plain, width, height))
