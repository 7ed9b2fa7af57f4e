"""Local worker pools that render work units: threads or forked processes, one interface.

Threads share everything, and Embree's run() and large NumPy loops release the GIL,
but the many small NumPy calls of a wavefront bounce hold it: on 2 cores threads reach
about 1.6x.  Forked processes (Linux) each own a copy of the prepared RenderSession (its
Embree scene already committed) and reach close to 2x; unit results travel back as arrays.
Inside Blender (bpy imported) the process is never forked.

Every pool offers start(units), next_result(timeout) -> (unit, UnitResult or None when
cancelled, error) or None, cancel(), close() and `describe`; RenderSession.run drives any of
them (engine/pools/dask_cluster.py is the Dask one).  A unit's random numbers do not depend on where it
runs, so the image does not depend on the pool.
"""
from __future__ import annotations

import ctypes
import os
import queue
import signal
import sys
import threading
import traceback
from concurrent.futures import ThreadPoolExecutor

PARALLELISM = ("auto", "threads", "processes")


def choose_parallelism(requested: str, workers: int) -> str:
    if requested != "auto":
        return requested
    forkable = sys.platform.startswith("linux") and "bpy" not in sys.modules
    return "processes" if workers > 1 and forkable else "threads"


class ThreadWorkers:
    describe = "threads"

    def __init__(self, session, count: int):
        self.session = session
        self.cancel_event = threading.Event()
        self.finished: queue.Queue = queue.Queue()
        self.pool = ThreadPoolExecutor(max_workers=count)

    def _work(self, unit):
        try:
            self.finished.put((unit, self.session.render_unit(unit, self.cancel_event), None))
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

    def cancel(self):
        self.cancel_event.set()

    def close(self):
        self.cancel_event.set()
        self.pool.shutdown(wait=True)


_FORKED_SESSION = None   # set just before fork; the children inherit it


PR_SET_PDEATHSIG = 1


def die_with_parent(parent_pid: int) -> None:
    """In a forked worker: SIGKILL when the parent dies (Linux prctl), so a killed render leaves no
    orphan; ignore SIGINT (a terminal's Ctrl-C reaches the whole group: the parent decides)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent_pid:          # the parent died before prctl took effect
        os._exit(1)


def _process_main(tasks, results, cancel_event, parent_pid):
    die_with_parent(parent_pid)
    session = _FORKED_SESSION
    while True:
        unit = tasks.get()
        if unit is None:
            return
        try:
            results.put((unit, session.render_unit(unit, cancel_event), None))
        except BaseException:
            results.put((unit, None, traceback.format_exc()))


class ProcessWorkers:
    describe = "processes"

    def __init__(self, session, count: int):
        global _FORKED_SESSION
        # imported here: importing multiprocessing aliases sys.modules["__mp_main__"] to __main__, and in
        # Blender 3.4 that stale module crashes addon_utils.disable_all when Blender quits
        import multiprocessing
        ctx = multiprocessing.get_context("fork")
        self.tasks = ctx.Queue()
        self.results = ctx.Queue()
        self.cancel_event = ctx.Event()
        _FORKED_SESSION = session
        try:
            self.procs = [ctx.Process(target=_process_main, args=(self.tasks, self.results, self.cancel_event,
                                                                     os.getpid()),
                                      daemon=True) for _ in range(count)]
            for p in self.procs:
                p.start()
        finally:
            _FORKED_SESSION = None

    def start(self, units):
        """May be called again with more units (the passes of engine/rendering/stopping.py)."""
        for unit in units:
            self.tasks.put(unit)

    def next_result(self, timeout: float):
        try:
            unit, result, error = self.results.get(timeout=timeout)
        except queue.Empty:
            if not any(p.is_alive() for p in self.procs) and self.results.empty():
                raise RuntimeError("TNCG15 MC: all render worker processes died") from None
            return None
        if isinstance(error, str):
            error = RuntimeError(f"render worker failed:\n{error}")
        return unit, result, error

    def cancel(self):
        self.cancel_event.set()

    def close(self):
        self.cancel_event.set()
        for _ in self.procs:
            self.tasks.put(None)                 # the end of the units
        for p in self.procs:
            p.join(timeout=5)
            if p.is_alive():
                p.terminate()


def make_workers(kind: str, session, count: int):
    return ProcessWorkers(session, count) if kind == "processes" else ThreadWorkers(session, count)
