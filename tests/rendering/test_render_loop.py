"""Tiles stream through the callback, progress is reported, cancel keeps what was rendered."""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.scene.builtin import cornell_scene

from tests.scenes import camera_inside_sphere_scene


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
    from engine.rendering.session import RenderSession
    scene = camera_inside_sphere_scene(albedo=0.8, emission=1.0, resolution=(64, 64))
    session = RenderSession(scene, RenderSettings(samples=64, threads=1, seed=5, max_depth=400), log=lambda *a: None)
    cancel = CancelAfter(3)
    assert session.render_unit(session.units[0], cancel) is None
    assert cancel.looks == 4                                  # stopped at the first look after 3 bounces
    finished = session.render_unit(session.units[0])
    n = finished.count.sum()
    mean = finished.sum[:, 0].sum() / n
    se = np.sqrt((finished.sum_sq[:, 0].sum() / n - mean ** 2) / n)
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
    import engine.rendering.session
    import engine.rendering.units
    from engine.rendering.session import RenderSession
    monkeypatch.setattr(engine.rendering.units, "UNIT_PATHS", 2048)       # 8 samples of a 16 x 16 tile per unit
    scene = cornell_scene((48, 32))
    settings = RenderSettings(samples=40, tile_size=16, threads=2, seed=9)
    reference = render(scene, settings, log=lambda *a: None)
    session = RenderSession(scene, settings, log=lambda *a: None)
    assert len(session.units) > len(session.tiles)          # several sample chunks per tile
    for unit in reversed(session.units):
        session.add(session.render_unit(unit))
    assert np.array_equal(session.film.mean(), reference.image)


def test_progressive_passes_refine_the_whole_frame_first():
    from engine.rendering.session import RenderSession
    session = RenderSession(cornell_scene((64, 64)), RenderSettings(samples=64, tile_size=16), log=lambda *a: None,
                            progressive="passes")
    first = session.units[:len(session.tiles)]
    assert sorted(u.tile.index for u in first) == list(range(len(session.tiles)))
    assert all(u.chunk == 0 for u in first)


def test_a_cancelled_render_keeps_units_that_finished_out_of_order(monkeypatch):
    """Chunk 1 of a tile done, chunk 0 cancelled: the merge in order would wait for chunk 0
    forever; a cancelled render keeps chunk 1 (finished work is never thrown away)."""
    import engine.rendering.session
    import engine.rendering.units
    from engine.rendering.session import RenderSession
    monkeypatch.setattr(engine.rendering.units, "UNIT_PATHS", 2048)
    session = RenderSession(cornell_scene((32, 32)), RenderSettings(samples=32, tile_size=16, seed=2),
                            log=lambda *a: None)
    tile0 = [u for u in session.units if u.tile.index == 0]
    assert len(tile0) >= 2 and tile0[1].chunk == 1
    assert session.add(session.render_unit(tile0[1])) == []            # waits for chunk 0
    assert not session.film.count.any()
    assert [t.index for t in session.film.flush()] == [0]
    assert session.film.count[:16, :16].min() == tile0[1].stop - tile0[1].start
    assert session.film.mean()[:16, :16].mean() > 0 and session.film.flush() == []
