"""Caustic photon batches as work units of the render session: each batch traced once, by
whichever worker is free, and shared with every worker whose units gather from it.

A camera unit of samples start .. stop - 1 gathers from the photon passes of those samples, which
are traced in batches (engine/integrators/photons/caustics.py batches_of).  `PhotonScheduler` is a
pool (engine/pools/protocol.py) around the render's pool that the frame side drives as any other
(engine/rendering/frame.py Frame.run, the rounds of engine/rendering/stopping.py, the viewport's
frames): for the camera units it is given it

* starts a PhotonUnit (engine/rendering/units.py) for each batch they need, at most LOOKAHEAD ahead
  of the units that wait for one, so the workers trace the next batch while they render the last;
* holds each camera unit back until the batches it needs are traced, then starts it: with a pool
  whose `shares_photons` is true (threads, forked processes, worker processes, the viewport's) it
  first hands the batch's photons to every worker (pool.share_photons(batch, stored)), and drops
  them (pool.forget_photons(batches)) once no unit left needs them; a pool whose `resolves_photons`
  is true (Dask) takes every unit at once and passes each batch to the units that need it itself;
* answers the camera units as the pool does and keeps the photon units' answers to itself: their
  counters (photons traced, stored, rays, trace seconds, radius per pass) go to the frame's.

Camera units start in the order of the first batch they need (pass-major: the whole frame
refines), so a batch is needed for a short while only.  Every batch's photons are the same
whichever worker traces them, so the image is bit for bit the one each worker tracing its own
passes renders (a pool that does neither, or a batch that was not shared, falls back to that).
The time the photons take is render time: the stopping rules' time limit, rates and error
estimate see it as the rounds' wall time (engine/rendering/stopping.py).
"""
from __future__ import annotations

import collections
import itertools
import time

from ..integrators.photons.caustics import batches_of
from .units import PhotonUnit

LOOKAHEAD = 2      # photon batches started and not yet shared, at most: the next is traced while the last renders
_SCHEDULERS = itertools.count(1)


def photon_scheduled(pool, frame):
    """`pool` as the frame's units need it: a PhotonScheduler when the frame gathers caustic
    photons and the pool can share them, else the pool itself."""
    if not frame.plan.enabled.get("photon_caustics"):
        return pool
    if getattr(pool, "shares_photons", False) or getattr(pool, "resolves_photons", False):
        return PhotonScheduler(pool, frame.totals)
    return pool


class PhotonScheduler:
    """The Pool of engine/pools/protocol.py around `pool` that traces each photon batch once
    (see the module's docstring); `totals`: the frame's Counters, which get the photon units'."""

    def __init__(self, pool, totals):
        self.pool, self.totals = pool, totals
        self.number = next(_SCHEDULERS)           # on its PhotonUnits: answers to another render's are ignored
        self.describe = pool.describe
        self.takes_rounds = pool.takes_rounds
        self.resolves = getattr(pool, "resolves_photons", False) and not getattr(pool, "shares_photons", False)
        self.held: list = []                      # camera units waiting for their batches, in start order
        self.needs: dict = {}                     # camera unit -> its batches
        self.wanted: collections.deque = collections.deque()    # batches to trace, in order of first need
        self.tracing: set = set()                 # batches whose photon unit runs
        self.shared: set = set()                  # batches traced (and shared)
        self.users = collections.Counter()        # batch -> camera units started or held that need it
        self.answers: collections.deque = collections.deque()   # camera units answered here (cancelled)
        self.cancelled = False
        self.photon_units = 0
        self.photon_seconds = 0.0                 # summed over the photon units (worker seconds)
        self.share_seconds = 0.0                  # handing the batches over (this side's seconds)
        self.shared_bytes = 0                     # photon bytes handed over, per worker

    # -- the pool protocol ---------------------------------------------------------------------------
    def prepare(self, scene, settings):
        return self.pool.prepare(scene, settings)

    def start(self, units) -> None:
        units = sorted(units, key=lambda u: (batches_of(u.start, u.stop).start, u.index))
        for unit in units:
            needs = tuple(batches_of(unit.start, unit.stop))
            self.needs[unit] = needs
            for b in needs:
                self.users[b] += 1
                if b not in self.shared and b not in self.tracing and b not in self.wanted:
                    self.wanted.append(b)
        if self.resolves:                          # Dask: every batch and unit at once
            batches = list(self.wanted)
            self.wanted.clear()
            self.tracing.update(batches)
            self.photon_units += len(batches)
            self.pool.start([PhotonUnit(b, self.number) for b in batches] + units)
            return
        self.held.extend(units)
        self._advance()

    def _advance(self) -> None:
        """Start the held units whose batches are shared, and the next photon units."""
        if self.cancelled:
            return
        ready = [u for u in self.held if all(b in self.shared for b in self.needs[u])]
        if ready:
            chosen = set(ready)
            self.held = [u for u in self.held if u not in chosen]
            self.pool.start(ready)
        more = []
        while self.wanted and len(self.tracing) + len(more) < LOOKAHEAD:
            more.append(self.wanted.popleft())
        if more:
            self.tracing.update(more)
            self.photon_units += len(more)
            self.pool.start([PhotonUnit(b, self.number) for b in more])

    def next_result(self, timeout: float):
        deadline = time.perf_counter() + timeout
        while True:
            if self.answers:
                return self.answers.popleft()
            item = self.pool.next_result(max(0.0, deadline - time.perf_counter()))
            if item is None:
                return None
            unit, result, error = item
            if not isinstance(unit, PhotonUnit):
                self._done(unit)
                return item
            if unit.scheduler != self.number or unit.batch not in self.tracing:
                continue                           # an earlier render's, answered late (the viewport's pool lives on)
            self.tracing.discard(unit.batch)
            if error is not None or result is None:
                # A failed photon unit fails the units that need it (the frame side cancels the rest);
                # one cancelled (the pool was cancelled) leaves them cancelled.
                self._drop_held(error)
                continue
            self.totals.merge(result.counters)
            self.photon_seconds += result.seconds
            if not self.resolves:
                start = time.perf_counter()
                self.pool.share_photons(unit.batch, result.stored)
                self.share_seconds += time.perf_counter() - start
                self.shared_bytes += stored_bytes(result.stored)
            self.shared.add(unit.batch)
            self._advance()

    def _drop_held(self, error) -> None:
        for i, unit in enumerate(self.held):
            self.answers.append((unit, None, error if i == 0 else None))
            self._done(unit)
        self.held = []
        if error is not None:
            self.cancel()

    def _done(self, unit) -> None:
        """A camera unit was answered: forget the batches no unit needs any more (but the last one
        traced, which the next round of the stopping rules may start in)."""
        needs = self.needs.pop(unit, ())
        unused = []
        for b in needs:
            self.users[b] -= 1
            if self.users[b] <= 0:
                del self.users[b]
                unused.append(b)
        latest = max(self.shared, default=-1)
        unused = [b for b in unused if b in self.shared and b != latest]
        if unused and not self.resolves:
            self.shared.difference_update(unused)
            self.pool.forget_photons(unused)

    def cancel(self) -> None:
        if not self.cancelled:
            self.cancelled = True
            self.wanted.clear()
            for unit in self.held:
                self.answers.append((unit, None, None))
                self.needs.pop(unit, None)
            self.held = []
        self.pool.cancel()

    def close(self) -> None:
        self.pool.close()

    def stats(self) -> dict:
        return self.pool.stats()

    def warnings(self) -> list:
        return self.pool.warnings()

    def photon_stats(self) -> dict:
        """What the frame's stats say of the photon units (engine/rendering/frame.py)."""
        return {"photon_units": self.photon_units, "photon_unit_seconds": self.photon_seconds,
                "share_seconds": self.share_seconds, "shared_bytes_per_worker": self.shared_bytes,
                "distribution": "shared" if not self.resolves else "dask dependencies"}


def stored_bytes(stored) -> int:
    """The bytes of a batch's stored photons (engine/integrators/photons/tracing.py Stored)."""
    return sum(a.nbytes for a in (stored.position, stored.incoming, stored.flux, stored.normal, stored.segments,
                                  stored.label, stored.chain) if a is not None)
