"""Tiles stream through the callback, progress is reported, cancel keeps what was rendered."""
import numpy as np

from engine import RenderSettings, render
from engine.default_scene import cornell_scene

from .scenes import camera_inside_sphere_scene


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
    calls = {"n": 0}
    tiles = []

    def should_cancel():
        calls["n"] += 1
        return len(tiles) >= 1

    result = render(cornell_scene((128, 128)), RenderSettings(samples=64, tile_size=16, threads=1),
                    on_tile=lambda *a: tiles.append(a[:4]), should_cancel=should_cancel, log=lambda *a: None)
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


def test_a_cancelled_tile_is_not_biased_towards_short_paths():
    """Cancel after 3 bounces of the wavefront inside the white furnace (L = 5 everywhere).

    Samples that finish first are the paths Russian roulette ended early, which carry less
    light (about 2.4); a partial tile must still average 5, so the paths already in flight
    are traced to their end instead of being dropped."""
    from engine.geometry import Counters
    from engine.render import Renderer, Tile
    scene = camera_inside_sphere_scene(albedo=0.8, emission=1.0, resolution=(64, 64))
    renderer = Renderer(scene, RenderSettings(samples=64, threads=1, seed=5, max_depth=400), log=lambda *a: None)
    film = renderer.render_tile(Tile(0, 0, 0, 64, 64), CancelAfter(3), Counters())
    n = film.count.sum()
    assert 0 < n < 64 * 64 * 64                      # partial
    mean = film.sum[:, 0].sum() / n
    se = np.sqrt((film.sum_sq[:, 0].sum() / n - mean ** 2) / n)
    assert abs(mean - 5.0) < 4 * se, f"partial tile mean {mean:.4f} +- {se:.4f}, expected 5"
