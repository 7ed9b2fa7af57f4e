"""Tiles stream through the callback, progress is reported, cancel keeps what was rendered."""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.rendering.frame import Frame
from engine.rendering.session import PreparedScene
from engine.scene.builtin import cornell_scene

from tests.scenes import camera_inside_sphere_scene


def prepare(scene, settings, progressive="tiles"):
    """The two sides of a render by hand: the tracer side and the frame side."""
    prepared = PreparedScene(scene, settings, log=lambda *a: None)
    return prepared, Frame(scene, settings, prepared.facts(), progressive)


def test_tiles_cover_the_image_and_match_the_result():
    seen = []
    progress = []
    result = render(cornell_scene((40, 24)), RenderSettings(samples=2, tile_size=16),
                    on_tile=lambda x0, y0, x1, y1, px: seen.append((x0, y0, x1, y1, px.copy())),
                    on_progress=lambda f, msg: progress.append(f), log=lambda *a: None)
    assert len(seen) == 6  # 3 x 2 tiles
    covered = np.zeros((24, 40), dtype=int)
    for x0, y0, x1, y1, px in seen:
        assert px.shape == (y1 - y0, x1 - x0, 3) and px.dtype == np.float32
        assert np.array_equal(px, result.image[y0:y1, x0:x1])
        covered[y0:y1, x0:x1] += 1
    assert (covered == 1).all()
    assert progress[-1] == 1.0 and progress == sorted(progress)
    assert not result.cancelled


def test_cancel_stops_early_and_keeps_finished_tiles():
    tiles = []
    result = render(cornell_scene((128, 128)), RenderSettings(samples=64, tile_size=16, threads=1),
                    on_tile=lambda *a: tiles.append(a[:4]), should_cancel=lambda: len(tiles) >= 1,
                    log=lambda *a: None)
    assert result.cancelled and result.stats["cancelled"]
    assert 1 <= len(tiles) < 64
    x0, y0, x1, y1 = tiles[0]
    assert result.image[y0:y1, x0:x1].mean() > 0  # the finished tile is kept
    assert result.stats["rays"]["camera"] < 128 * 128 * 64 / 4


class CancelAfter:
    """A cancel event that is set from its (k+1)-th look on: the tracer looks once per bounce."""

    def __init__(self, k):
        self.k, self.looks = k, 0

    def is_set(self):
        self.looks += 1
        return self.looks > self.k


def test_a_cancelled_unit_is_dropped_whole():
    """Cancel after 3 bounces: the unit returns nothing (a partial unit would keep only the paths
    that Russian roulette ended early, about 2.4 in the white furnace instead of 5)."""
    scene = camera_inside_sphere_scene(albedo=0.8, emission=1.0, resolution=(64, 64))
    settings = RenderSettings(samples=64, threads=1, seed=5, max_depth=400)
    prepared, frame = prepare(scene, settings)
    cancel = CancelAfter(3)
    assert prepared.render_unit(frame.units[0], cancel) is None
    assert cancel.looks == 4                                  # stopped at the first look after 3 bounces
    finished = prepared.render_unit(frame.units[0])
    n = finished.count.sum()
    mean = finished.sum[..., 0].sum() / n
    se = np.sqrt((finished.sum_sq[..., 0].sum() / n - mean ** 2) / n)
    assert abs(mean - 5.0) < 4 * se


@pytest.mark.slow   # statistical; the kept and dropped units: the two cancel tests above
def test_a_cancelled_render_keeps_unbiased_finished_units():
    """The furnace again, cancelled part-way: every pixel that has samples averages 5."""
    units = []
    scene = camera_inside_sphere_scene(albedo=0.8, emission=1.0, resolution=(64, 64))
    result = render(scene, RenderSettings(samples=256, threads=2, max_depth=400),
                    on_progress=lambda f, msg: units.append(f), should_cancel=lambda: len(units) >= 3,
                    log=lambda *a: None)
    assert result.cancelled and 1 <= result.stats["units_done"] < result.stats["units"]   # progress events can precede merges
    lit = result.image[..., 0] > 0
    assert lit.any() and abs(result.image[..., 0][lit].mean() - 5.0) < 0.05


def test_units_in_any_order_give_the_same_image_bit_for_bit(monkeypatch):
    """Units rendered by hand in reverse order, merged into a fresh film: the same image as a
    normal render, whatever order the units finish in."""
    import engine.rendering.units
    monkeypatch.setattr(engine.rendering.units, "UNIT_PATHS", 2048)       # 8 samples of a 16 x 16 tile per unit
    scene = cornell_scene((48, 32))
    settings = RenderSettings(samples=40, tile_size=16, threads=2, seed=9)
    reference = render(scene, settings, log=lambda *a: None)
    prepared, frame = prepare(scene, settings)
    assert len(frame.units) > len(frame.tiles)              # several sample chunks per tile
    for unit in reversed(frame.units):
        frame.add(prepared.render_unit(unit))
    assert np.array_equal(frame.film.mean(), reference.image)


def test_progressive_order_frame_refines_the_whole_frame_first():
    _, frame = prepare(cornell_scene((64, 64)), RenderSettings(samples=64, tile_size=16), progressive="frame")
    first = frame.units[:len(frame.tiles)]
    assert sorted(u.tile.index for u in first) == list(range(len(frame.tiles)))
    assert all(u.chunk == 0 for u in first)


def test_a_cancelled_render_keeps_units_that_finished_out_of_order(monkeypatch):
    """Chunk 1 of a tile done, chunk 0 cancelled: the merge in order would wait for chunk 0
    forever; a cancelled render keeps chunk 1 (finished work is never thrown away)."""
    import engine.rendering.units
    monkeypatch.setattr(engine.rendering.units, "UNIT_PATHS", 2048)
    prepared, frame = prepare(cornell_scene((32, 32)), RenderSettings(samples=32, tile_size=16, seed=2))
    tile0 = [u for u in frame.units if u.tile.index == 0]
    assert len(tile0) >= 2 and tile0[1].chunk == 1
    assert frame.add(prepared.render_unit(tile0[1])) == []             # waits for chunk 0
    assert not frame.film.count.any()
    assert [t.index for t in frame.film.flush()] == [0]
    assert frame.film.count[:16, :16].min() == tile0[1].stop - tile0[1].start
    assert frame.film.mean()[:16, :16].mean() > 0 and frame.film.flush() == []
