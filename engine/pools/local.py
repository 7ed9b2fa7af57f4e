"""Local pools that render work units in this process's threads or in forked processes.

Threads share everything, and Embree's run() and large NumPy loops release the GIL,
but the many small NumPy calls of a wavefront bounce hold it: on 2 cores threads reach
about 1.6x.  Forked processes (Linux) each own a copy of the prepared scene (its Embree scene
already committed: prepare() builds it here, then forks) and reach close to 2x; unit results
travel back as arrays.  Inside Blender (bpy imported) the process is never forked.
Both are pools of engine/pools/protocol.py.
"""
from __future__ import annotations

import os
import queue
import signal
import sys
import threading
import time
import traceback
from concurrent.futures import ThreadPoolExecutor

from ..rendering.session import PreparedScene
from .faults import CANCEL_SECONDS, POLL, Dispatch, Worker
from .protocol import Pool
from .transport import describe_exit, die_with_parent

PARALLELISM = ("auto", "threads", "processes")


def choose_parallelism(requested: str, workers: int) -> str:
    if requested != "auto":
        return requested
    forkable = sys.platform.startswith("linux") and "bpy" not in sys.modules
    return "processes" if workers > 1 and forkable else "threads"


class ThreadPool(Pool):
    describe = "threads"
    shares_photons = True         # one prepared scene: a photon batch shared is every thread's

    def __init__(self, count: int, log=print):
        self.count, self.log = max(1, count), log
        self.prepared = None
        self.cancel_event = threading.Event()
        self.finished: queue.Queue = queue.Queue()
        self.pool = ThreadPoolExecutor(max_workers=self.count)

    def prepare(self, scene, settings):
        self.prepared = PreparedScene(scene, settings, log=self.log)
        return self.prepared.facts()

    def _work(self, unit):
        try:
            self.finished.put((unit, self.prepared.render_unit(unit, self.cancel_event), None))
        except BaseException as exc:  # surfaced on the calling thread
            self.finished.put((unit, None, exc))

    def start(self, units):
        for unit in units:
            self.pool.submit(self._work, unit)

    def next_result(self, timeout: float):
        try:
            return self.finished.get(timeout=timeout)
        except queue.Empty:
            return None

    def share_photons(self, batch, stored):
        self.prepared.share_photons(batch, stored)

    def forget_photons(self, batches):
        self.prepared.forget_photons(batches)

    def cancel(self):
        self.cancel_event.set()

    def close(self):
        self.cancel_event.set()
        self.pool.shutdown(wait=True)


_FORKED_SCENE = None   # set just before fork; the children inherit it


class SharedFlag:
    """A cancel flag in shared memory without a lock: a worker killed while reading it (SIGKILL,
    the OOM killer) leaves no lock held that would block the parent's set() (a multiprocessing
    Event's would)."""

    def __init__(self, ctx):
        self.value = ctx.RawValue("b", 0)

    def set(self):
        self.value.value = 1

    def is_set(self) -> bool:
        return bool(self.value.value)


def _process_main(conn, cancel_flag, parent_pid):
    die_with_parent(parent_pid)
    prepared = _FORKED_SCENE
    # A reader thread empties the pipe while a unit renders, so the parent's write of a photon batch
    # (megabytes) never waits for the unit, and never meets this worker's write of its result.
    inbox: queue.Queue = queue.Queue()

    def read():
        while True:
            try:
                message = conn.recv()
            except (EOFError, OSError):
                message = None
            inbox.put(message)
            if message is None:
                return
    threading.Thread(target=read, daemon=True).start()
    while True:
        unit = inbox.get()
        if unit is None:
            return
        if isinstance(unit, tuple):             # ("share", batch, stored) | ("forget", batches): photon batches
            if unit[0] == "share":
                prepared.share_photons(unit[1], unit[2])
            else:
                prepared.forget_photons(unit[1])
            continue
        try:
            answer = (unit, prepared.render_unit(unit, cancel_flag), None)
        except BaseException:
            answer = (unit, None, traceback.format_exc())
        try:
            conn.send(answer)
        except (BrokenPipeError, OSError):
            return


class _Fork(Worker):
    """A forked worker: its process and its own pipe (a worker killed mid-message breaks no other's)."""

    def __init__(self, number, ctx, cancel_flag):
        super().__init__()
        self.conn, child = ctx.Pipe(duplex=True)
        self.proc = ctx.Process(target=_process_main, args=(child, cancel_flag, os.getpid()), daemon=True)
        self.proc.start()
        child.close()
        self.ready = True                        # it inherits the prepared scene
        self.name = f"render worker {number} (pid {self.proc.pid})"
        self.outbox = None                       # a writer thread's queue, from the first photon batch on

    def send_unit(self, unit):
        if self.outbox is not None:
            self.outbox.put(unit)
            return
        try:
            self.conn.send(unit)
        except (BrokenPipeError, OSError):
            pass                                 # it died: its sentinel reports it

    def send_bytes(self, payload: bytes):
        """A pickled message (megabytes: a photon batch) written by a thread of its own, so the frame
        side never waits for the pipe; the units sent after it take the same thread, in order."""
        if self.outbox is None:
            self.outbox = queue.Queue()
            threading.Thread(target=self._write, daemon=True, name="tncg15-fork-writer").start()
        self.outbox.put(payload)

    def _write(self):
        while True:
            message = self.outbox.get()
            try:
                if isinstance(message, bytes):
                    self.conn.send_bytes(message)
                else:
                    self.conn.send(message)
            except (BrokenPipeError, OSError, ValueError):
                return                           # it died (its sentinel reports it) or the pool closed
            if message is None:
                return

    def kill(self):
        try:
            os.kill(self.proc.pid, signal.SIGKILL)
        except OSError:
            pass


class ForkPool(Pool):
    """Forked processes; faults as in engine/pools/faults.py (a dead or stopped worker's units
    are rendered by the others)."""

    describe = "processes"
    shares_photons = True

    def __init__(self, count: int, log=print):
        self.count, self.log = max(1, count), log
        self.workers: list[_Fork] = []
        # imported here: importing multiprocessing aliases sys.modules["__mp_main__"] to __main__, and in
        # Blender 3.4 that stale module crashes addon_utils.disable_all when Blender quits
        import multiprocessing
        self.ctx = multiprocessing.get_context("fork")
        self.cancel_flag = SharedFlag(self.ctx)
        self.dispatch = Dispatch(self.workers, log=log)

    def prepare(self, scene, settings):
        """Prepare the scene here, then fork the workers: each inherits it."""
        global _FORKED_SCENE
        prepared = PreparedScene(scene, settings, log=self.log)
        _FORKED_SCENE = prepared
        try:
            for i in range(self.count):
                self.workers.append(_Fork(i + 1, self.ctx, self.cancel_flag))
        finally:
            _FORKED_SCENE = None
        return prepared.facts()

    @property
    def procs(self):
        return [w.proc for w in self.workers]

    def start(self, units):
        self.dispatch.start(units)

    def next_result(self, timeout: float):
        from multiprocessing.connection import wait
        deadline = time.perf_counter() + timeout
        while True:
            answer = self.dispatch.check()
            if answer is not None:
                return answer
            live = self.dispatch.alive()
            if not live:
                return None
            waiting = {w.conn: w for w in live}
            waiting.update({w.proc.sentinel: w for w in live})
            ready = wait(list(waiting), timeout=max(0.0, min(POLL, deadline - time.perf_counter())))
            for handle in ready:
                worker = waiting[handle]
                if not worker.alive:
                    continue
                answer = self._receive(worker)
                if answer is not None:
                    return answer
            if time.perf_counter() >= deadline:
                return None

    def _receive(self, worker):
        """The worker's next answer, or what its death means (engine/pools/faults.py)."""
        try:
            if worker.conn.poll():
                unit, result, error = worker.conn.recv()
                if unit not in worker.in_flight:
                    return None                  # already answered (given up after a cancel)
                self.dispatch.finished(worker, unit)
                if isinstance(error, str):
                    error = RuntimeError(f"{worker.name} failed:\n{error}")
                return unit, result, error
        except (EOFError, OSError):
            pass
        if worker.proc.is_alive():
            return None
        worker.proc.join()
        return self.dispatch.died(worker, describe_exit(worker.proc.exitcode))

    def share_photons(self, batch, stored):
        """A photon batch to every live worker, pickled once (engine/rendering/photon_passes.py);
        each worker's writer thread keeps it ahead of the units sent after it."""
        self._tell(("share", batch, stored))

    def forget_photons(self, batches):
        self._tell(("forget", list(batches)))

    def _tell(self, message):
        from multiprocessing.reduction import ForkingPickler
        payload = bytes(ForkingPickler.dumps(message))
        for w in self.workers:
            if w.alive:
                w.send_bytes(payload)

    def cancel(self):
        self.cancel_flag.set()
        self.dispatch.cancel()

    def close(self):
        self.dispatch.closing = True
        self.cancel_flag.set()
        for w in self.workers:
            if w.alive:
                w.send_unit(None)                # the end of the units
        end = time.perf_counter() + CANCEL_SECONDS     # then SIGKILL: a stopped worker never ends
        for w in self.workers:
            w.proc.join(timeout=max(0.0, end - time.perf_counter()))
            if w.proc.is_alive():
                w.kill()
                w.proc.join()
            w.conn.close()

    def stats(self) -> dict:
        return {"worker_reports": list(self.dispatch.reports)} if self.dispatch.reports else {}

    def warnings(self) -> list:
        return list(self.dispatch.reports)
