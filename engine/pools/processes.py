"""Render worker processes that any Python can host: the tracer outside Blender's interpreter.

A worker is ``python -m <tracer package> worker <parent pid>`` (engine/cli/main.py) spoken to over
the transport of engine/pools/transport.py (framed pickles, the hello with the engine version,
the stderr tail, close and kill, death with the parent).  After the hello:

    parent -> worker   ("prepare", scene, settings)          once: the worker builds a PreparedScene
                       ("unit", WorkUnit)                     any number (or a PhotonUnit)
                       ("share", batch, stored photons)       a photon batch traced by some worker
                       ("forget", batches)                    photon batches no unit needs now
    worker -> parent   ("ready", TracerFacts)                 accelerator, effect plan, build time
                       ("result", unit, UnitResult | None)    None: cancelled, dropped whole
                       ("error", unit, traceback text)

SIGUSR1 cancels: the event passed to render_unit is set, so a busy worker stops within a bounce and
answers every unit left with None.  EOF on stdin ends the worker.

`SubprocessPool` is the pool (engine/pools/protocol.py): it starts the workers when it is made,
before the scene exists (their imports overlap the export), sends the scene once to each in
prepare(), and dispatches the units with the fault model of engine/pools/faults.py: two units in
flight per worker, a worker that dies or stops answering reported by name and its units rendered by
the others.
"""
from __future__ import annotations

import os
import queue
import signal
import sys
import threading
import time
import traceback

from ..core.paths import TRACER_DIR, worker_environment
from .faults import POLL, Dispatch, Worker
from .protocol import Pool
from .transport import WorkerEnd, WorkerProcess, close_all, encode, log_to_stderr, send_to_live, start_workers

START_TIMEOUT = 120.0                     # seconds for imports + scene + BVH before a worker is given up
CLOSE_SECONDS = 2.0                       # EOF, then SIGKILL


class WorkerError(RuntimeError):
    """A worker could not start or died; the message names it and says why."""


# -- the worker -----------------------------------------------------------------------------------
def worker_main(parent_pid: int) -> int:
    """`python -m engine worker PARENT_PID`: prepare one scene, render the units sent."""
    from ..core.allocator import tune_malloc
    from ..rendering.session import PreparedScene
    cancel = threading.Event()
    signal.signal(signal.SIGUSR1, lambda *_: cancel.set())
    end = WorkerEnd(parent_pid)
    if not end.handshake():
        return end.exit_code
    message = end.receive()
    if message is None:
        return 0
    _, scene, settings = message
    tune_malloc()
    prepared = PreparedScene(scene, settings, log=log_to_stderr)
    end.send(("ready", prepared.facts()))
    while True:
        message = end.receive()
        if message is None:
            return 0
        if message[0] == "share":
            prepared.share_photons(message[1], message[2])
            continue
        if message[0] == "forget":
            prepared.forget_photons(message[1])
            continue
        _, unit = message
        try:
            end.send(("result", unit, prepared.render_unit(unit, cancel)))
        except Exception:                       # noqa: BLE001 - the parent reports it with the unit
            end.send(("error", unit, traceback.format_exc()))


# -- the parent side ------------------------------------------------------------------------------
class _Worker(WorkerProcess, Worker):
    """A render worker and the units it holds (engine/pools/faults.py)."""

    def __init__(self, number: int, python: str, env: dict, events: queue.Queue):
        Worker.__init__(self)
        self.number = number
        WorkerProcess.__init__(self, python, [os.path.basename(TRACER_DIR), "worker"], env, f"render worker {number}",
                               on_message=lambda w, m: events.put((w, m)),
                               on_exit=lambda w, code: events.put((w, ("died", code))))

    def send_unit(self, unit):
        self.send(("unit", unit))

    def kill(self):
        self.signal(signal.SIGKILL)


class SubprocessPool(Pool):
    """Worker processes of `python` (`count` of them, started here); faults as in
    engine/pools/faults.py."""

    shares_photons = True

    def __init__(self, python: str, count: int, extra_paths=(), log=print):
        self.python, self.log = python, log
        self.events: queue.Queue = queue.Queue()
        env = worker_environment(extra_paths)
        self.workers = start_workers(
            lambda number: _Worker(number, python, env, self.events), count, CLOSE_SECONDS,
            lambda why: WorkerError(f"TNCG15 MC: cannot start render workers with {python}: {why}"))
        self.describe = f"{len(self.workers)} worker process(es) ({python})"
        self.dispatch = Dispatch(self.workers, log=log, start_seconds=START_TIMEOUT)
        self.reports = self.dispatch.reports    # workers that died, by name
        self.facts = None
        self.ready_seconds = None
        self._started = time.perf_counter()
        self._early: list = []                  # events seen while waiting for "ready"

    # -- preparation ----------------------------------------------------------------------------
    def prepare(self, scene, settings, timeout: float = START_TIMEOUT):
        """Send the scene to every worker; wait for the first to be ready and return its facts."""
        payload = encode(("prepare", scene, settings), views=True)
        for w in self.workers:
            w.send(payload)
        deadline = time.perf_counter() + timeout
        while self.facts is None:
            try:
                worker, event = self.events.get(timeout=max(0.01, deadline - time.perf_counter()))
            except queue.Empty:
                self.close()
                raise WorkerError(f"render workers ({self.python}) did not start within {timeout:.0f} s") from None
            if event[0] == "ready":
                self.dispatch.became_ready(worker)
                self.facts = event[1]
                self.ready_seconds = time.perf_counter() - self._started
            elif event[0] == "died":
                worker.alive = False
                self.reports.append(f"{worker.name} died while starting: {worker.why(event[1])}")
                if not any(w.alive for w in self.workers):
                    self.close()
                    raise WorkerError(start_failure(self.python, worker))
            else:
                self._early.append((worker, event))
        for w in self.facts.warnings:
            self.log(f"warning: {w}")
        return self.facts

    # -- the pool protocol ----------------------------------------------------------------------
    def start(self, units):
        self.dispatch.start(units)

    def next_result(self, timeout: float):
        deadline = time.perf_counter() + timeout
        while True:
            answer = self.dispatch.check()
            if answer is not None:
                return answer
            if self._early:
                worker, event = self._early.pop(0)
            else:
                try:
                    worker, event = self.events.get(timeout=max(0.0, min(POLL, deadline - time.perf_counter())))
                except queue.Empty:
                    if time.perf_counter() >= deadline:
                        return None
                    continue
            answer = self._event(worker, event)
            if answer is not None:
                return answer

    def _event(self, worker, event):
        kind = event[0]
        if kind == "ready":
            self.dispatch.became_ready(worker)
            return None
        if kind == "died":
            return self.dispatch.died(worker, worker.why(event[1]))
        unit = event[1]
        if unit not in worker.in_flight:
            return None                         # already answered (given up after a cancel)
        self.dispatch.finished(worker, unit)
        if kind == "error":
            where = f"tile {unit.tile.index}" if hasattr(unit, "tile") else repr(unit)
            return unit, None, WorkerError(f"{worker.name} failed on {where}:\n{event[2]}")
        return unit, event[2], None

    def share_photons(self, batch, stored):
        """A photon batch to every live worker, encoded once (engine/rendering/photon_passes.py)."""
        send_to_live(self.workers, ("share", batch, stored))

    def forget_photons(self, batches):
        send_to_live(self.workers, ("forget", list(batches)))

    def cancel(self):
        if self.dispatch.cancelled:
            return
        self.dispatch.cancel()
        for w in self.workers:
            if w.alive:
                w.signal(signal.SIGUSR1)

    def close(self):
        self.dispatch.closing = True
        close_all(self.workers, CLOSE_SECONDS)

    def stats(self) -> dict:
        return {"workers_ready_seconds": self.ready_seconds, "worker_python": self.python,
                "worker_python_version": self.facts.python if self.facts is not None else None,
                "worker_reports": list(self.reports)}

    def warnings(self) -> list:
        return list(self.reports)


def start_failure(python: str, worker) -> str:
    """Why the first worker could not start, as one sentence naming what to install."""
    text = "\n".join(worker.stderr_tail)
    for name in ("numpy", "embreex"):
        if f"No module named '{name}'" in text:
            return (f"TNCG15 MC: the Python for render workers ({python}) has no {name}: install it "
                    f"({python} -m pip install numpy embreex) or choose another interpreter in the "
                    "add-on's Preferences (Python for render workers)")
    return f"TNCG15 MC: {worker.name} could not start: {worker.why(worker.proc.poll())}"


if __name__ == "__main__":
    from .transport import exit_worker
    exit_worker(worker_main(int(sys.argv[1])))
