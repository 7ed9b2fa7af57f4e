"""A unit's samples added to its film in sample order, whatever order the paths finish in.

The wavefront (engine/integrators/path_tracer.py) hands finished paths over bounce by bounce, so
which of a pixel's samples arrive together depends on the wavefront's size; floating-point sums
depend on that grouping in their last bits.  OrderedSamples keeps each sample's radiance in the
slot of its (sample, pixel) until the unit's range is traced, then adds them all at once: every
pixel's samples are summed one after the other in sample order (Film.add_samples' bincount adds in
index order), so the film's sums, and the image, are the same bit for bit whatever the wavefront
size (tests/film/test_ordered_samples.py).  It holds 3 float64 and one flag per camera sample of the
range (about 25 bytes a path: 6.5 MB for a unit of 2^18 paths).
"""
from __future__ import annotations

import numpy as np


class OrderedSamples:
    """The samples first .. stop-1 of a tile's `pixels` pixels, for `film` (engine/film/accumulator.py)."""

    def __init__(self, film, pixels: int, first: int, stop: int):
        self.film, self.pixels, self.first = film, pixels, first
        size = max(stop - first, 0) * pixels
        self.radiance = np.zeros((3, size))
        self.filled = np.zeros(size, dtype=bool)

    def add(self, pixel: np.ndarray, radiance: np.ndarray, sample: np.ndarray) -> None:
        """Samples' radiance rows (3, N) of tile pixels `pixel` and sample numbers `sample`."""
        slot = (sample - self.first) * self.pixels + pixel
        for row, values in zip(self.radiance, radiance):     # a 1-D scatter a row: twice as fast as [:, slot]
            row[slot] = values
        self.filled[slot] = True

    def flush(self) -> None:
        """Add every kept sample to the film, in sample order per pixel."""
        if self.filled.all():               # the film is the tile's (engine/rendering/session.py)
            assert self.film.width * self.film.height == self.pixels, "a tile's samples on another film"
            self.film.add_every_pixel(self.radiance)
        else:
            slot = np.flatnonzero(self.filled)
            self.film.add_samples(slot % self.pixels, self.radiance.take(slot, axis=1))
