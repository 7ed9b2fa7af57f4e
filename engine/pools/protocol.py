"""The pool protocol: what renders a frame's work units, whatever and wherever its workers are.

engine/api.py render() and the frame side (engine/rendering/frame.py Frame.run, the stopping
rules of engine/rendering/stopping.py) drive any pool the same way:

    facts = pool.prepare(scene, settings)   # every worker builds the tracer side (PreparedScene)
    pool.start(units)                       # any number of times when pool.takes_rounds
    pool.next_result(timeout)               # (unit, UnitResult or None, error or None), or None
    pool.cancel()                           # running units stop within a bounce, answered with None
    pool.close()                            # always, once: no worker or unit of this render is left
    pool.stats(), pool.warnings()           # what the pool adds to the render's stats and warnings
    pool.share_photons(batch, stored)       # optional (shares_photons): a caustic photon batch to every worker
    pool.forget_photons(batches)            # ... and dropped (engine/rendering/photon_passes.py)

A unit's random numbers do not depend on where it runs and the frame merges each tile's units in
order, so the image never depends on the pool.  engine/pools/spec.py make_pool builds a pool from
a spec ("threads", "processes", "workers:PYTHON", "dask:ADDRESS").
"""
from __future__ import annotations

from abc import ABC, abstractmethod


class Pool(ABC):
    """A pool renders one frame: prepare() once, then start() / next_result(), then close()."""

    describe: str = "pool"        # for the stats' "parallelism" and the log ("threads", "dask local (2 workers)")
    takes_rounds: bool = True     # start() may be called again with more units (the stopping rules' rounds)
    shares_photons: bool = False  # share_photons / forget_photons reach every worker (engine/rendering/photon_passes.py)
    resolves_photons: bool = False  # start() takes photon units with the units that need them, and passes them on

    @abstractmethod
    def prepare(self, scene, settings):
        """Have the tracer side (engine/rendering/session.py PreparedScene) built where the units
        run; returns the TracerFacts of one prepared scene (accelerator, effect plan, warnings).
        Raises SceneError (or a subclass) with one line when the scene or the workers cannot render."""

    @abstractmethod
    def start(self, units) -> None:
        """Queue work units (engine/rendering/units.py WorkUnit) to render."""

    @abstractmethod
    def next_result(self, timeout: float):
        """(unit, UnitResult, None) for a finished unit, (unit, None, None) for a cancelled one,
        (unit, None, exception) for a failed one, or None when none finished within `timeout`."""

    @abstractmethod
    def cancel(self) -> None:
        """Stop the units in flight (each is answered as cancelled) and start no more."""

    @abstractmethod
    def close(self) -> None:
        """Stop and release the workers; the pool is done."""

    def stats(self) -> dict:
        """Keys the pool adds to the render's stats (e.g. the worker Python)."""
        return {}

    def warnings(self) -> list:
        """Messages the pool adds to the render's warnings (e.g. workers that died)."""
        return []
