"""The fault model of engine/pools/faults.py on a Dask cluster (engine/pools/dask_cluster.py DaskPool):
what the scheduler shows of a render's units, read every WATCH_SECONDS, and what to do about it.

A Dask scheduler notices a worker whose connection closes (SIGKILL, a crash) at once and runs its
units elsewhere, but a worker that stops answering with its connection open (SIGSTOP, a hung
process, a network link cut) only after `distributed.scheduler.worker-ttl`, 5 minutes by default
(docs/cluster-and-viewport.md A3).  So the pool watches, as the local pools do:

* `units_on_workers` (run on the scheduler) lists, per worker, the render's units it processes.
* `UnitClock` keeps, per worker, since when it holds units and finished none, and the slowest unit
  measured so far (the time between two of a worker's units leaving it).  A worker past
  faults.unit_deadline(slowest) (plus DEADLINE_FACTOR x the scene's preparation time before its
  first unit) is overdue.
* `drop_worker` (run on the scheduler) removes an overdue worker as if it had died: its units go
  back to the queue and run on the others, and the scene task is recomputed if it held the only
  copy.  Units are deterministic, so the image is bit-identical.
* No worker left for NO_WORKER_SECONDS (a nanny restarts a killed worker within about a second):
  the render ends with one line and keeps its finished units (engine/core/errors.py WorkersLost).

The two scheduler functions travel by value (their module is set to __main__): the scheduler has
no copy of this project (it unpickles every task: docs/cluster-and-viewport.md A4).
"""
from __future__ import annotations

from . import faults

WATCH_SECONDS = 0.5        # between two looks at the scheduler
NO_WORKER_SECONDS = 10.0   # the scheduler without a usable worker this long: no worker is left


def units_on_workers(dask_scheduler, prefix):
    """On the scheduler: {worker address: [keys starting with `prefix` it is processing]}, every worker."""
    return {address: sorted(str(ts.key) for ts in ws.processing if str(ts.key).startswith(prefix))
            for address, ws in dask_scheduler.workers.items()}


async def drop_worker(dask_scheduler, address, why):
    """On the scheduler: remove `address` as a dead worker (its tasks are rescheduled)."""
    return await dask_scheduler.remove_worker(address, stimulus_id=f"tncg15-{why}", close=True)


for _fn in (units_on_workers, drop_worker):
    _fn.__module__ = "__main__"


class UnitClock:
    """Per worker: the units it held at the last look, since when it finished none, whether it
    finished any (its first unit also prepares the scene: `first_extra` more seconds)."""

    def __init__(self, first_extra: float = 0.0):
        self.first_extra = first_extra
        self.held: dict = {}
        self.busy_since: dict = {}
        self.finished_any: set = set()
        self.slowest = 0.0
        self.dropped: set = set()

    def limit(self, worker) -> float:
        return faults.unit_deadline(self.slowest) + (0.0 if worker in self.finished_any else self.first_extra)

    def observe(self, view: dict, now: float) -> list:
        """Take the scheduler's `view` (units_on_workers) at time `now`; returns [(worker, limit)]
        of the workers overdue now (each reported once)."""
        for worker in list(self.held):
            if worker not in view:                   # gone from the scheduler: nothing to watch
                self.held.pop(worker)
                self.busy_since.pop(worker, None)
        for worker, keys in view.items():
            keys, before = frozenset(keys), self.held.get(worker, frozenset())
            if not keys:
                self.busy_since.pop(worker, None)
            elif not before or worker not in self.busy_since:
                self.busy_since[worker] = now
            elif before - keys:                      # a unit left it: finished
                if worker in self.finished_any:
                    self.slowest = max(self.slowest, now - self.busy_since[worker])
                self.finished_any.add(worker)
                self.busy_since[worker] = now
            if before and not keys:
                self.finished_any.add(worker)
            self.held[worker] = keys
        overdue = []
        for worker, since in self.busy_since.items():
            limit = self.limit(worker)
            if worker not in self.dropped and now - since > limit:
                self.dropped.add(worker)
                overdue.append((worker, limit))
        return overdue
