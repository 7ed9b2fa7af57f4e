"""Python's cyclic garbage collector paused while a scene is prepared.

Preparing a scene (engine/rendering/session.py PreparedScene) loads numba's compiled kernels from
its cache and builds the scene's tables: some 90,000 long-lived objects and no garbage, for which
the collector ran about 200 times (measured with gc.callbacks on the built-in Cornell box,
2026-12-05); preparing many_lights (256²) took 0.80 CPU s with them and 0.71 without (medians of
5 fresh processes alternated, load 9-11).
A render's units create no reference cycles to speak of (no collection at all in a second 256²,
16 spp render of the Cornell, caustic or many_lights scene), so the collector stays on for them.
"""
from __future__ import annotations

import gc
from contextlib import contextmanager


@contextmanager
def collector_paused():
    """gc disabled inside, restored to what it was on leaving (also on an exception)."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
