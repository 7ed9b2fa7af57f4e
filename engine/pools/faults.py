"""The fault model of the pools whose workers are processes started here: forked processes
(engine/pools/local.py ForkPool), worker processes of any Python (engine/pools/processes.py
SubprocessPool) and the viewport's (engine/pools/viewport.py); a Dask cluster's workers get the
same deadline through its scheduler (engine/pools/dask_watch.py).  One `Dispatch` per render keeps the units: which are pending, which each worker
holds, and what happens when a worker fails.

* Dispatch: each worker gets its first unit before any gets a second; at most IN_FLIGHT units are
  queued on a worker, a second only while many are pending (`queues_another`).
* A worker that dies (its process exits, its pipe ends) is named in the render's warnings and the
  units it held are queued again at the front, for the other workers.  Units are deterministic
  (engine/rendering/units.py: a unit's random numbers depend on the frame only), so the image is
  bit-identical to an undisturbed render.  A unit lost twice is an error: it may be what kills
  its workers.
* A worker that stops answering (SIGSTOP, a hang) is found by a unit deadline: a worker holding
  units and finishing none for `unit_deadline()` seconds, max(DEADLINE_MIN, DEADLINE_FACTOR x the
  slowest unit measured so far in this render), is killed by its pool; then it is a worker that
  died, above.  A worker still building its scene has `start_seconds` instead.
* No worker left: the unit that was lost is answered with `WorkersLost` (one line); the frame keeps
  the units that finished (engine/rendering/frame.py) and the command lines write them.
* Cancel: units never sent are answered as cancelled at once; a worker that has not answered its
  units CANCEL_SECONDS after the cancel is killed and its units are answered as cancelled, so
  Ctrl-C returns within about a second whatever the workers do.

A pool's workers subclass `Worker` (the bookkeeping) and implement send_unit() and kill().
"""
from __future__ import annotations

import collections
import time

from ..core.errors import WorkersLost

IN_FLIGHT = 2            # units queued per worker, so none waits for the next (Dispatch.feed)
DEADLINE_MIN = 30.0      # seconds: a worker finishing no unit for this long (at least) is killed
DEADLINE_FACTOR = 10.0   # ... or for this many times the slowest unit so far, if longer
CANCEL_SECONDS = 1.0     # after a cancel, a worker still holding units this long is killed
POLL = 0.1               # seconds between deadline checks while a pool waits for a result
QUEUE_AHEAD_ROUNDS = 2   # a second unit is queued only while more than this many per worker are pending


def queues_another(held: int, pending: int, alive: int) -> bool:
    """Whether a worker holding `held` units is sent one more (below its IN_FLIGHT): its first
    always; another only while more than QUEUE_AHEAD_ROUNDS units per live worker are pending.  A
    queued unit waits for its worker even when another is idle, so the last units of a render go
    one at a time to whichever worker is free (a round of few units of the stopping rules ended
    when the worker holding two big ones did, docs/performance.md "Worker processes"; a final render
    of 5 units of unequal tiles, 96x96 at 64 spp, left one worker idle 0.3-0.6 s with the rule of
    one unit per worker, "A render's fixed cost")."""
    return held == 0 or pending > QUEUE_AHEAD_ROUNDS * alive


def unit_deadline(slowest: float) -> float:
    """Seconds a worker holding units may finish none before it is given up: `slowest` is the
    slowest unit measured so far in this render (engine/pools/dask_watch.py uses it too)."""
    return max(DEADLINE_MIN, DEADLINE_FACTOR * slowest)


class Worker:
    """The dispatch's bookkeeping of one worker; a pool's worker class adds the process."""

    name = "render worker"

    def __init__(self):
        self.alive, self.ready = True, False
        self.in_flight: list = []
        self.busy_since = time.perf_counter()    # since when it works on its first unit in flight
        self.overdue = None                      # why it was killed, if the dispatch had it killed

    def send_unit(self, unit) -> None:
        raise NotImplementedError

    def kill(self) -> None:
        raise NotImplementedError


class Dispatch:
    """The units of one render on `workers` (Worker objects): pending, held, finished, lost."""

    def __init__(self, workers, log=print, start_seconds: float = 0.0):
        self.workers = workers
        self.log = log
        self.start_seconds = start_seconds
        self.pending: collections.deque = collections.deque()
        self.retried: set = set()                # unit indices already queued again once
        self.reports: list[str] = []             # workers that died, by name and why
        self.slowest = 0.0                       # seconds of the slowest unit finished so far
        self.cancelled_at = None
        self.closing = False

    @property
    def cancelled(self) -> bool:
        return self.cancelled_at is not None

    def alive(self) -> list:
        return [w for w in self.workers if w.alive]

    # -- dispatch ---------------------------------------------------------------------------------
    def start(self, units) -> None:
        self.pending.extend(units)
        for w in self.workers:                  # every worker its first unit before any takes a second
            self.feed(w, limit=1)
        for w in self.workers:
            self.feed(w)

    def feed(self, worker, limit: int = IN_FLIGHT) -> None:
        """Send `worker` units until it has `limit` in flight, a second one only where
        queues_another says."""
        alive = len(self.alive())
        while (worker.alive and not self.cancelled and self.pending and len(worker.in_flight) < limit
               and queues_another(len(worker.in_flight), len(self.pending), alive)):
            unit = self.pending.popleft()
            if not worker.in_flight:
                worker.busy_since = time.perf_counter()
            worker.in_flight.append(unit)
            worker.send_unit(unit)              # if it died, its death queues the unit again

    def became_ready(self, worker) -> None:
        """`worker` has built its scene: its deadline counts from now."""
        worker.ready = True
        worker.busy_since = time.perf_counter()

    def finished(self, worker, unit) -> None:
        """`worker` answered `unit` (a result, a cancelled unit or an error)."""
        now = time.perf_counter()
        if unit in worker.in_flight:
            worker.in_flight.remove(unit)
            if worker.ready:
                self.slowest = max(self.slowest, now - worker.busy_since)
        worker.busy_since = now
        self.feed(worker)

    # -- faults -----------------------------------------------------------------------------------
    def unit_deadline(self) -> float:
        return unit_deadline(self.slowest)

    def check(self):
        """Kill the workers past their deadline (their deaths come back through died()); after a
        cancel, answer the units of workers that did not stop in time.  Returns a cancelled unit's
        answer (unit, None, None) or None."""
        now = time.perf_counter()
        if self.cancelled:
            if self.pending:
                return self.pending.popleft(), None, None     # never sent: dropped like a cancelled unit
            if now - self.cancelled_at > CANCEL_SECONDS:
                for w in self.workers:
                    if w.in_flight:
                        w.alive = False
                        w.kill()
                        return w.in_flight.pop(0), None, None
            return None
        for w in self.alive():
            limit = self.unit_deadline() + (0.0 if w.ready else self.start_seconds)
            if w.in_flight and w.overdue is None and now - w.busy_since > limit:
                w.overdue = f"stopped answering: no unit finished in {limit:.0f} s (killed)"
                w.kill()
        return None

    def died(self, worker, why: str):
        """`worker`'s process ended (`why`: how).  Its units are queued again for the others and it
        is reported; returns None, or (unit, None, WorkersLost) when no worker is left or a unit was
        lost twice."""
        worker.alive = False
        lost, worker.in_flight = worker.in_flight, []
        if self.cancelled or self.closing:
            self.pending.extend(lost)           # answered as cancelled by check()
            return None
        message = f"{worker.name} died: {worker.overdue or why}"
        self.reports.append(message)
        self.log(f"warning: {message}")
        survivors = self.alive()
        again = [u for u in lost if u.index not in self.retried]
        if not survivors or len(again) < len(lost):
            self.pending.extend(lost)
            failed = self.pending.popleft() if self.pending else None
            return failed, None, WorkersLost(message + ("; no render worker is left" if not survivors else
                                                        "; its unit had already been retried once"))
        self.retried.update(u.index for u in again)
        self.pending.extendleft(reversed(again))
        for w in survivors:
            self.feed(w)
        return None

    def cancel(self) -> None:
        if not self.cancelled:
            self.cancelled_at = time.perf_counter()
