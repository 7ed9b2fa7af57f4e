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
import sys
import threading
import traceback
from concurrent.futures import ThreadPoolExecutor

from ..rendering.session import PreparedScene
from .protocol import Pool
from .transport import die_with_parent

PARALLELISM = ("auto", "threads", "processes")


def choose_parallelism(requested: str, workers: int) -> str:
    if requested != "auto":
        return requested
    forkable = sys.platform.startswith("linux") and "bpy" not in sys.modules
    return "processes" if workers > 1 and forkable else "threads"


class ThreadPool(Pool):
    describe = "threads"

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

    def cancel(self):
        self.cancel_event.set()

    def close(self):
        self.cancel_event.set()
        self.pool.shutdown(wait=True)


_FORKED_SCENE = None   # set just before fork; the children inherit it


def _process_main(tasks, results, cancel_event, parent_pid):
    die_with_parent(parent_pid)
    prepared = _FORKED_SCENE
    while True:
        unit = tasks.get()
        if unit is None:
            return
        try:
            results.put((unit, prepared.render_unit(unit, cancel_event), None))
        except BaseException:
            results.put((unit, None, traceback.format_exc()))


class ForkPool(Pool):
    describe = "processes"

    def __init__(self, count: int, log=print):
        self.count, self.log = max(1, count), log
        self.procs = []
        # imported here: importing multiprocessing aliases sys.modules["__mp_main__"] to __main__, and in
        # Blender 3.4 that stale module crashes addon_utils.disable_all when Blender quits
        import multiprocessing
        self.ctx = multiprocessing.get_context("fork")
        self.tasks = self.ctx.Queue()
        self.results = self.ctx.Queue()
        self.cancel_event = self.ctx.Event()

    def prepare(self, scene, settings):
        """Prepare the scene here, then fork the workers: each inherits it."""
        global _FORKED_SCENE
        prepared = PreparedScene(scene, settings, log=self.log)
        _FORKED_SCENE = prepared
        try:
            self.procs = [self.ctx.Process(target=_process_main, args=(self.tasks, self.results, self.cancel_event,
                                                                          os.getpid()),
                                           daemon=True) for _ in range(self.count)]
            for p in self.procs:
                p.start()
        finally:
            _FORKED_SCENE = None
        return prepared.facts()

    def start(self, units):
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
