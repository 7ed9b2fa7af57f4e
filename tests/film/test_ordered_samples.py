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
