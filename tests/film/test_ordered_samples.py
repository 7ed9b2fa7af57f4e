"""engine/film/ordered_samples.py: a unit's film sums are the same bit for bit whatever the
wavefront size (engine/integrators/path_tracer.py WAVEFRONT_SIZE), under the Sobol' sampler.

Control: adding each bounce's finished paths straight to the film (as before OrderedSamples)
gives sums that differ in their last bits between wavefront sizes."""
import numpy as np
import pytest

import engine.integrators.path_tracer as path_tracer
from engine.core.settings import RenderSettings
from engine.film.accumulator import Film
from engine.film.ordered_samples import OrderedSamples
from engine.rendering.session import PreparedScene
from engine.rendering.units import Tile, WorkUnit
from engine.scene.builtin import caustic_scene, cornell_scene


def unit_sums(prepared, unit, wavefront, monkeypatch):
    monkeypatch.setattr(path_tracer, "WAVEFRONT_SIZE", wavefront)
    result = prepared.render_unit(unit)
    return result.sum, result.sum_sq, result.count


@pytest.mark.parametrize("make_scene, halves", [(cornell_scene, False), (caustic_scene, True)])
def test_film_sums_do_not_depend_on_the_wavefront_size(make_scene, halves, monkeypatch):
    prepared = PreparedScene(make_scene((32, 32)), RenderSettings(samples=24, threads=1, seed=3), log=lambda *a: None)
    unit = WorkUnit(0, Tile(0, 8, 8, 24, 24), 0, 2, 24, halves=halves)        # 256 pixels x 22 samples
    reference = unit_sums(prepared, unit, 1 << 15, monkeypatch)              # the whole unit in one wavefront
    for wavefront in (512, 2048):
        sums = unit_sums(prepared, unit, wavefront, monkeypatch)
        assert all(np.array_equal(a, b) for a, b in zip(sums, reference)), wavefront


def test_control_bounce_by_bounce_sums_depend_on_the_wavefront(monkeypatch):
    """Without the sample order, the same paths give other last bits at another wavefront size."""
    def straight(self, pixel, radiance, sample):
        self.film.add_samples(pixel, radiance)
    monkeypatch.setattr(OrderedSamples, "add", straight)
    monkeypatch.setattr(OrderedSamples, "flush", lambda self: None)
    prepared = PreparedScene(cornell_scene((32, 32)), RenderSettings(samples=24, threads=1, seed=3),
                             log=lambda *a: None)
    unit = WorkUnit(0, Tile(0, 8, 8, 24, 24), 0, 2, 24)
    big, small = unit_sums(prepared, unit, 1 << 15, monkeypatch), unit_sums(prepared, unit, 512, monkeypatch)
    assert np.array_equal(big[2], small[2]) and np.allclose(big[0], small[0], rtol=1e-12)
    assert not np.array_equal(big[0], small[0])


def test_masked_ranges_keep_their_samples_in_order():
    """Samples arriving out of order, of some pixels only: each pixel summed in sample order."""
    film = Film(4, 1)
    ordered = OrderedSamples(film, 4, 3, 6)                      # samples 3, 4, 5 of pixels 1 and 3
    values = {(p, s): [1.0, 1e16, -1e16][s - 3] * (p + 1) for p in (1, 3) for s in (3, 4, 5)}
    for p, s in [(3, 5), (1, 4), (3, 3), (1, 5), (3, 4), (1, 3)]:
        ordered.add(np.array([p]), np.full((3, 1), values[p, s]), np.array([s]))
    ordered.flush()
    assert film.count[0].tolist() == [0, 3, 0, 3]
    # (1 + 1e16) - 1e16 is 0 in float64, the arrival order (1e16 - 1e16) + 1 would give 1.
    assert film.sum[0, :, 0].tolist() == [0.0, (2.0 + 2e16) - 2e16, 0.0, (4.0 + 4e16) - 4e16] == [0.0] * 4


def _slots_as_before(ordered, pixel, radiance, sample):
    """OrderedSamples.add as it was written before the row-by-row scatter: one 2-D fancy assignment."""
    slot = (sample - ordered.first) * ordered.pixels + pixel
    ordered.radiance[:, slot] = radiance
    ordered.filled[slot] = True


def _added_both_ways(pixel, radiance, sample, add=OrderedSamples.add):
    mine, before = OrderedSamples(Film(4, 1), 5, 2, 6), OrderedSamples(Film(4, 1), 5, 2, 6)
    add(mine, pixel, radiance, sample)
    _slots_as_before(before, pixel, radiance, sample)
    return mine, before


def _some_samples():
    """Arrivals of a unit (5 pixels, samples 2..5) with NaN, inf, -0.0, a repeated slot (the later
    value stays) and radiance rows that are a strided view, as a wavefront's rows may be."""
    rng = np.random.default_rng(7)
    pixel = np.array([0, 4, 2, 2, 1, 3, 0])
    sample = np.array([2, 5, 3, 3, 4, 2, 5])
    radiance = rng.normal(size=(6, 7))[::2]
    radiance[0, 1], radiance[1, 2], radiance[2, 5] = np.nan, np.inf, -0.0
    return pixel, radiance, sample


def test_add_scatters_as_the_two_dimensional_assignment():
    for pixel, radiance, sample in (_some_samples(), (np.zeros(0, int), np.zeros((3, 0)), np.zeros(0, int))):
        mine, before = _added_both_ways(pixel, radiance, sample)
        assert np.array_equal(mine.radiance, before.radiance, equal_nan=True)
        assert np.array_equal(np.signbit(mine.radiance), np.signbit(before.radiance))
        assert np.array_equal(mine.filled, before.filled)


def test_control_a_wrong_scatter_is_caught():
    """A scatter that writes the rows in another order differs from the assignment."""
    def rows_swapped(self, pixel, radiance, sample):
        OrderedSamples.add(self, pixel, radiance[::-1], sample)
    mine, before = _added_both_ways(*_some_samples(), add=rows_swapped)
    assert not np.array_equal(mine.radiance, before.radiance, equal_nan=True)
