"""The viewport: a pool of worker processes kept across views, and its progressive render.

`ViewportPool` (made by engine/pools/spec.py ``make_pool("viewport[:PYTHON]", n)``) is a pool of
engine/pools/protocol.py whose workers, ``python -m <tracer package>.pools.viewport PARENT_PID``
over the transport of engine/pools/transport.py, outlive a render: prepare() may be called again
after every started unit was answered, and a scene that differs from the last one in its camera
and resolution only (the same objects otherwise, as dataclasses.replace makes it) with the same
settings is not prepared again: the workers get the new camera (no BVH rebuild).

    parent -> worker   ("prepare", number, scene, settings, checked)   build a PreparedScene (checked:
                                                           the parent validated the scene, engine/rendering/session.py)
                       ("view", camera, resolution)           the prepared scene's new camera
                       ("unit", WorkUnit)                     trace it (or a PhotonUnit)
                       ("share", batch, stored) | ("forget", batches)   photon batches (engine/rendering/photon_passes.py)
                       ("cancel",)                            the units before it stop within a bounce
                       ("warm",)                              idle workers started ahead (mcrt_addon/warm.py):
                                                           import numba, load its kernels from a warm cache
                                                           now or once it is warm (warm_kernels)
    worker -> parent   ("ready", number, TracerFacts) | ("failed", number, one line)
                       ("warmed", loaded)                     after ("warm",): kernels loaded, or nothing to load
                       ("result", unit, UnitResult | None)    None: cancelled
                       ("error", unit, traceback text)

Faults as in engine/pools/faults.py: a worker that dies, or holds units and finishes none for the
unit deadline (faults.unit_deadline of the slowest unit so far: SIGSTOP, a hang), is killed, named
in the pool's reports (the viewport's header shows the last: ViewportRender.notice) and started
again with the scene and view of the moment (at most MAX_RESTARTS times); its units go to the
others first.  After a cancel, a worker that has not answered its units within
faults.CANCEL_SECONDS is killed (its units are answered as cancelled) and restarted, so a new
view never waits for a stopped worker.

A reader thread in the worker sets the cancel event as soon as ("cancel",) arrives, so the unit
in progress stops within a bounce and the units queued before the cancel are answered None; the
cancel clears when the worker reaches it in the stream, so the units after it render.

`ViewportRender` is the progressive render the 3D viewport shows (mcrt_addon/viewport.py): on
a thread of the parent it renders each view as frames of the frame side (engine/rendering/frame.py
Frame, one film each), as Cycles' viewport does: coarse frames of 1 sample, the first at the
resolution divided by the power of two that leaves at most `start_resolution`² pixels (Cycles'
Performance > Viewport > Start Pixels, `start_divider`), each next one at twice the resolution,
then the view itself at the resolution divided by the pixel size (Cycles' Pixel Size) in the
"growing" order of engine/rendering/units.py (one sample of the whole frame, then units of 1, 2,
4, ... samples), until `target` samples.  A new scene or view cancels the frame in progress
(engine/rendering/units.py await_units) and starts again.  Every picture carries the `tag` of the
request it was rendered for (the viewport's view), so a picture of an old view is never taken
for the new one; the picture shown (image, noise) is made on the render thread, never on the
caller's (Blender's UI thread), whose snapshot() only reads it.
With the Sobol' sampler a sample number gives the same random numbers wherever it is traced, so
the picture after `target` samples is the final render's image of that view with `target` samples.
"""
from __future__ import annotations

import dataclasses
import os
import queue
import signal
import sys
import threading
import time
import traceback
from typing import NamedTuple

import numpy as np

from ..core.errors import SceneError
from ..core.paths import TRACER_DIR, worker_environment
from . import faults
from .protocol import Pool
from .scene_delta import with_unchanged, without_unchanged
from .transport import (WorkerEnd, WorkerProcess, close_all, encode, exit_worker, log_to_stderr, send_to_live,
                        start_workers)

START_RESOLUTION = 64           # Cycles' default Start Pixels: the first frame has at most 64² pixels
IN_FLIGHT = 2                   # units queued per worker, so none waits for the next
START_TIMEOUT = 120.0           # seconds for imports + scene + BVH before the workers are given up
CLOSE_SECONDS = 1.0             # EOF, then SIGKILL
MAX_RESTARTS = 4                # dead workers started again, per pool (a worker that keeps dying stays dead)
NOTICE_SECONDS = 15.0           # the viewport's header shows a worker's death this long
WARM_POLL_SECONDS = 2.0         # a worker started ahead looks this often for numba's warm cache ...
WARM_WAIT_SECONDS = 300.0       # ... this long at most (watch_for_warm_cache)


class ViewportWorkerError(SceneError):
    """A viewport worker could not start, failed or died (one line, shown in the viewport's header)."""


def coarse_resolution(resolution, divider: int):
    """The resolution divided by `divider` (rounded up, at least one pixel)."""
    w, h = resolution
    return max(1, -(-w // divider)), max(1, -(-h // divider))


def start_divider(resolution, start_resolution: int = START_RESOLUTION, pixel_size: int = 1) -> int:
    """Cycles' rule for the first frame of a view: halve the resolution until it has at most
    start_resolution² pixels; the power of two it was divided by (at least the pixel size)."""
    w, h = resolution
    divider = 1
    while w * h > start_resolution * start_resolution and (w > 1 or h > 1):
        w, h, divider = max(1, w // 2), max(1, h // 2), divider * 2
    return max(divider, pixel_size)


def frame_dividers(resolution, start_resolution: int = START_RESOLUTION, pixel_size: int = 1) -> list[int]:
    """The dividers of one view's frames: the start divider, halved for every next (coarse)
    frame while it is above the pixel size, then the pixel size (the view's own frame)."""
    divider, out = start_divider(resolution, start_resolution, pixel_size), []
    while divider > pixel_size:
        out.append(divider)
        divider //= 2
    return out + [pixel_size]


class Picture(NamedTuple):
    """What the viewport shows: `version` changes whenever it does; rgba (h, w, 4) float32 with
    row 0 at the bottom, or None; samples the fewest any pixel of the view has (0 for a coarse
    frame); noise the relative error or None; level -1 (nothing yet), 0 (a coarse frame) or 1 (the
    view's own frame); error one line or None; tag the request's (the view it belongs to);
    divider the frame's resolution divider."""
    version: int
    rgba: object
    samples: int
    noise: object
    level: int
    error: object
    tag: object = None
    divider: int = 1


def one_line(exc) -> str:
    return str(exc) if isinstance(exc, SceneError) else f"{type(exc).__name__}: {exc}"


# -- the worker -----------------------------------------------------------------------------------
def warm_kernels() -> bool:
    """A worker started ahead of its first scene (mcrt_addon/warm.py) imports numba and, when its
    cache is warm, loads the compiled kernels (engine/core/backend.py) now: the first preparation
    then does neither (0.6 CPU s otherwise).  What a render runs is unchanged: the backend setting
    picks numba or NumPy as before (backend.resolve), loading only comes earlier.  False when the
    cache is not warm yet: the compile in the background that a render would start is started
    (backend.start_warm_up; none when one runs already)."""
    from ..core import backend
    from ..core.collector import collector_paused
    try:
        preimport()
        if backend.numba_module() is None:
            return True                         # nothing to load, ever
        if backend.is_warm():
            with collector_paused():            # long-lived objects only (engine/core/collector.py)
                backend.load_kernels()
            return True
        backend.start_warm_up(log=lambda *a: None)   # as the first render would (one compile per machine)
    except Exception:                           # noqa: BLE001 - the first prepare says why (backend.resolve)
        return True
    return False


def preimport() -> None:
    """Import now what a worker's first preparation would import (a worker started ahead is
    idle): the node programs' evaluator and its node modules, which engine/materials/textures.py
    imports at the first scene with a node program (22 modules, 30-50 CPU ms of that render in
    each worker, docs/performance.md "A render's fixed cost")."""
    from ..nodes import evaluator, registry          # noqa: F401 - the evaluator's own imports
    registry.kernels()                               # every node module


def watch_for_warm_cache(inbox: queue.Queue) -> None:
    """Until numba's cache is warm (a compile another process started, engine/core/backend.py
    start_warm_up), look for its stamp every WARM_POLL_SECONDS for at most WARM_WAIT_SECONDS (one
    stat of a few files each time); then ("warm",) to the worker's own inbox, which loads them."""
    from ..core import backend

    def watch():
        deadline = time.monotonic() + WARM_WAIT_SECONDS
        while time.monotonic() < deadline:
            time.sleep(WARM_POLL_SECONDS)
            if backend.is_warm():
                inbox.put(("warm",))
                return
    threading.Thread(target=watch, daemon=True, name="warm cache watch").start()


def viewport_worker_main(parent_pid: int) -> int:
    from ..core.allocator import tune_malloc
    from ..lights.environment import keep_last_map
    from ..rendering.session import PreparedScene
    keep_last_map()                         # a new preparation of the same world reuses its tables
    end = WorkerEnd(parent_pid)
    if not end.handshake():
        return end.exit_code
    tune_malloc()
    inbox: queue.Queue = queue.Queue()
    cancel = threading.Event()
    lock = threading.Lock()
    cancels = {"received": 0, "reached": 0}

    def read():
        while True:
            message = end.receive()
            if message is not None and message[0] == "cancel":
                with lock:
                    cancels["received"] += 1
                    cancel.set()
            inbox.put(message)
            if message is None:
                return

    threading.Thread(target=read, daemon=True).start()
    prepared, watching = None, False
    received, received_number = None, None     # the last scene sent (engine/pools/scene_delta.py)
    while True:
        message = inbox.get()
        if message is None:
            return 0
        kind = message[0]
        if kind == "cancel":
            with lock:
                cancels["reached"] += 1
                if cancels["reached"] == cancels["received"]:
                    cancel.clear()
        elif kind == "prepare":
            _, number, scene, settings, checked, kept = message
            prepared, received_was, number_was = None, received, received_number
            try:
                received, received_number = None, None      # until this one is complete
                scene = with_unchanged(scene, kept, received_was, number_was)
                received, received_number = scene, number
                prepared = PreparedScene(scene, settings, log=log_to_stderr, checked=checked)
                end.send(("ready", number, prepared.facts()))
            except Exception as exc:            # noqa: BLE001 - one line for the viewport's header
                end.send(("failed", number, one_line(exc)))
                if not isinstance(exc, SceneError):
                    print(traceback.format_exc(), file=sys.stderr)
        elif kind == "view":
            prepared.set_view(message[1], message[2])
        elif kind == "warm":
            loaded = warm_kernels()
            end.send(("warmed", loaded))
            if not loaded and not watching:
                watching = True
                watch_for_warm_cache(inbox)
        elif kind == "share" and prepared is not None:
            prepared.share_photons(message[1], message[2])
        elif kind == "forget" and prepared is not None:
            prepared.forget_photons(message[1])
        elif kind == "unit":
            unit = message[1]
            try:
                end.send(("result", unit, prepared.render_unit(unit, cancel)))
            except Exception:                   # noqa: BLE001 - the parent reports it with the unit
                end.send(("error", unit, traceback.format_exc()))


# -- the pool -------------------------------------------------------------------------------------
class _Worker(WorkerProcess):
    def __init__(self, number: int, python: str, env: dict, events: queue.Queue):
        self.number = number
        self.in_flight: list = []
        self.alive, self.prepared = True, None          # the preparation number it is ready for
        self.warmed = False                             # answered ("warm",) with its kernels loaded
        self.busy_since = time.perf_counter()           # since when it holds units and answered none
        self.overdue = None                             # why it was killed, when the pool killed it
        super().__init__(python, [os.path.basename(TRACER_DIR) + ".pools.viewport"], env,
                         f"viewport worker {number}", on_message=lambda w, m: events.put((w, m)),
                         on_exit=lambda w, code: events.put((w, ("died", code))), tail_lines=20)


def same_but_the_view(scene, other) -> bool:
    """`scene` is `other` with another camera or resolution only (every other field the same object)."""
    if other is None or type(scene) is not type(other):
        return False
    return all(getattr(scene, f.name) is getattr(other, f.name) for f in dataclasses.fields(scene)
               if f.name not in ("camera", "resolution"))


class ViewportPool(Pool):
    """`count` viewport worker processes of `python`, started here and kept until close()."""

    takes_rounds = True
    shares_photons = True

    def __init__(self, python: str, count: int = 1, extra_paths=(), log=print):
        self.python, self.log = python, log
        self.events: queue.Queue = queue.Queue()
        self.env = env = worker_environment(extra_paths)
        self.workers = start_workers(
            lambda number: _Worker(number, python, env, self.events), count, CLOSE_SECONDS,
            lambda why: ViewportWorkerError(f"TNCG15 MC: cannot start viewport workers with {python}: {why}"))
        self.describe = f"{len(self.workers)} viewport worker process(es) ({python})"
        self.pending: list = []
        self.cancelled = False
        self.preparation = 0                            # number of the last scene sent
        self.scene = self.settings = self.facts = None  # the scene prepared (its view: the last sent)
        self.checked = False                            # whether the caller validated it (prepare)
        self.sent = None                                # (number, scene) every worker holds (scene_delta.py)
        self.builds = 0                                 # scenes sent to be prepared, summed over the workers
        self.reports: list[str] = []                    # workers that died, by name
        self.report_times: list[float] = []
        self.restarts = 0
        self.slowest = 0.0                              # seconds of the slowest unit answered so far
        self.cancelled_at = None
        self.warming = False                            # warm() was asked: a restarted worker is asked too

    # -- preparation ----------------------------------------------------------------------------
    def prepare(self, scene, settings, timeout: float = START_TIMEOUT, checked: bool = False):
        """The scene on every worker: its camera and resolution only when nothing else changed,
        else the scene prepared again (waits for the first worker to be ready); checked: the caller
        validated `scene` (Scene.validate), the workers do not again."""
        self._give_up_cancelled()
        self.cancelled, self.pending, self.cancelled_at = False, [], None
        if self.facts is not None and settings == self.settings and same_but_the_view(scene, self.scene):
            scene.camera.validate()
            for w in self.workers:
                w.send(("view", scene.camera, tuple(scene.resolution)))
            self.scene = scene
            return self.facts
        self.preparation += 1
        self.scene, self.settings, self.facts, self.checked = scene, settings, None, checked
        shipped, kept = scene, (None, [])
        if checked and self.sent is not None:           # the arrays that did not change stay out
            shipped, kept = without_unchanged(scene, self.sent[1], self.sent[0])
        payload = encode(("prepare", self.preparation, shipped, settings, checked, kept), views=True)
        self.sent = (self.preparation, scene)
        for w in self.workers:
            w.prepared = None
            w.send(payload)
            self.builds += 1                # counted when sent, not when a worker's "ready" comes back
        deadline = time.perf_counter() + timeout
        failed = 0
        while self.facts is None:
            try:
                worker, event = self.events.get(timeout=max(0.01, deadline - time.perf_counter()))
            except queue.Empty:
                raise ViewportWorkerError(f"viewport workers ({self.python}) did not start within {timeout:.0f} s") from None
            self._event(worker, event)
            if event[0] == "failed" and event[1] == self.preparation:
                failed += 1
                if failed == sum(w.alive for w in self.workers) or failed == len(self.workers):
                    self.scene = None
                    raise SceneError(event[2])
            if not any(w.alive for w in self.workers):
                raise ViewportWorkerError(self.reports[-1] + "; no viewport worker is left")
        for w in self.facts.warnings:
            self.log(f"warning: {w}")
        return self.facts

    def _event(self, worker, event):
        """Bookkeeping of a worker's message: (unit, result, error) when it answers a unit."""
        kind = event[0]
        if worker not in self.workers:
            return None                                  # a worker given up and replaced
        if kind == "ready":
            if event[1] == self.preparation:
                worker.prepared = self.preparation
                worker.busy_since = time.perf_counter()
                if self.facts is None:
                    self.facts = event[2]
                self._feed(worker)
            return None
        if kind == "failed":
            self.sent = None            # the next scene goes whole (this worker may hold none)
            return None
        if kind == "warmed":
            worker.warmed = bool(event[1])
            return None
        if kind == "died":
            worker.alive = False
            message = f"{worker.name} died: {worker.overdue or worker.why(event[1])}"
            lost, worker.in_flight = worker.in_flight, []
            self.pending[:0] = lost                      # after a cancel: answered as cancelled
            replacement = self._restart(worker)
            if replacement is not None:
                message += f"; restarted as {replacement.name}"
            self._report(message)
            for w in self.workers:
                self._feed(w)
            if not any(w.alive for w in self.workers) and self.pending:
                return self.pending.pop(0), None, ViewportWorkerError(message + "; no viewport worker is left")
            return None
        unit = event[1]
        if unit in worker.in_flight:
            worker.in_flight.remove(unit)
            if worker.prepared == self.preparation:
                self.slowest = max(self.slowest, time.perf_counter() - worker.busy_since)
        worker.busy_since = time.perf_counter()
        self._feed(worker)
        if kind == "error":
            return unit, None, ViewportWorkerError(f"{worker.name} failed on tile {unit.tile.index}:\n{event[2]}")
        return unit, event[2], None

    def _feed(self, worker, limit: int = IN_FLIGHT):
        """Send `worker` units until it holds `limit`, a second one only where engine/pools/faults.py
        queues_another says (as Dispatch.feed): a unit queued on a busy worker waits for it even
        when another is idle (a final render on the workers started ahead, mcrt_addon/warm.py)."""
        alive = sum(w.alive for w in self.workers)
        while (worker.alive and worker.prepared == self.preparation and not self.cancelled and self.pending
               and len(worker.in_flight) < limit
               and faults.queues_another(len(worker.in_flight), len(self.pending), alive)):
            unit = self.pending.pop(0)
            if not worker.in_flight:
                worker.busy_since = time.perf_counter()
            worker.in_flight.append(unit)
            worker.send(("unit", unit))

    # -- faults (engine/pools/faults.py) ----------------------------------------------------------
    def _report(self, message):
        self.reports.append(message)
        self.report_times.append(time.perf_counter())
        self.log(f"warning: {message}")

    def _restart(self, dead):
        """A new worker in the place of `dead`, given the scene and view of the moment; None when
        the pool has restarted MAX_RESTARTS already or the new process cannot start."""
        if self.restarts >= MAX_RESTARTS or dead not in self.workers:
            return None
        try:
            worker = _Worker(dead.number, self.python, self.env, self.events)
        except OSError:
            return None
        self.restarts += 1
        self.workers[self.workers.index(dead)] = worker
        if self.warming:                                # else warmed() would wait for it for ever
            worker.send(("warm",))
        if self.scene is not None:
            worker.send(("prepare", self.preparation, self.scene, self.settings, self.checked, (None, [])))
            self.builds += 1
        else:                                           # it holds no scene the next one could refer to
            self.sent = None
        return worker

    def _check(self):
        """Kill the workers past their unit deadline (their deaths come back as events); after a
        cancel, give up the units of workers that have not answered in time.  Returns a cancelled
        unit's answer (unit, None, None) or None."""
        now = time.perf_counter()
        if self.cancelled:
            if self.cancelled_at is not None and now - self.cancelled_at > faults.CANCEL_SECONDS:
                for w in self.workers:
                    if w.alive and w.in_flight:
                        self._kill(w, f"did not stop within {faults.CANCEL_SECONDS:g} s of a cancel (killed)")
                        return w.in_flight.pop(0), None, None
                    if not w.alive and w.in_flight:
                        return w.in_flight.pop(0), None, None
            return None
        limit = faults.unit_deadline(self.slowest)
        for w in self.workers:
            if w.alive and w.in_flight and w.overdue is None and now - w.busy_since > limit:
                self._kill(w, f"stopped answering: no unit finished in {limit:.0f} s (killed)")
        return None

    def _kill(self, worker, why):
        worker.overdue = why
        worker.signal(signal.SIGKILL)

    def _give_up_cancelled(self):
        """Before a new render: the units of a cancelled one that some worker still holds are
        forgotten (a worker that does not stop is killed and restarted)."""
        if not self.cancelled:
            return
        for w in list(self.workers):
            if w.in_flight and w.alive and self.cancelled_at is not None \
                    and time.perf_counter() - self.cancelled_at > faults.CANCEL_SECONDS:
                self._kill(w, f"did not stop within {faults.CANCEL_SECONDS:g} s of a cancel (killed)")
            w.in_flight = [] if not w.alive or w.overdue else w.in_flight

    def outstanding(self) -> int:
        """Units started and not yet answered (queued here or held by a worker)."""
        return len(self.pending) + sum(len(w.in_flight) for w in self.workers if w.alive)

    def notice(self):
        """The last worker death of the last NOTICE_SECONDS (for the viewport's header), or None."""
        if self.reports and time.perf_counter() - self.report_times[-1] < NOTICE_SECONDS:
            return self.reports[-1]
        return None

    # -- the pool protocol ----------------------------------------------------------------------
    def start(self, units):
        self.pending.extend(units)
        for w in self.workers:                          # every worker one unit before any takes two
            self._feed(w, limit=1)
        for w in self.workers:
            self._feed(w)

    def next_result(self, timeout: float):
        if self.cancelled and self.pending:
            return self.pending.pop(0), None, None      # never sent: answered as cancelled
        if not any(w.alive for w in self.workers) and self.pending:
            return self.pending.pop(0), None, ViewportWorkerError("no viewport worker is left: " + "; ".join(self.reports))
        deadline = time.perf_counter() + timeout
        while True:
            answer = self._check()
            if answer is not None:
                return answer
            try:
                worker, event = self.events.get(timeout=max(0.0, min(faults.POLL, deadline - time.perf_counter())))
            except queue.Empty:
                if time.perf_counter() >= deadline:
                    return None
                continue
            answer = self._event(worker, event)
            if answer is not None:
                return answer

    def share_photons(self, batch, stored):
        """A photon batch to every live worker, encoded once (a worker started again later traces
        the batches it was not given itself: the same photons)."""
        send_to_live(self.workers, ("share", batch, stored))

    def forget_photons(self, batches):
        send_to_live(self.workers, ("forget", list(batches)))

    def warm(self):
        """Workers started ahead of their first scene load the compiled kernels now (warm_kernels)."""
        self.warming = True
        send_to_live(self.workers, ("warm",))

    def warmed(self) -> bool:
        """Whether every live worker has answered warm() with its kernels loaded (or with nothing to
        load).  It reads the pool's events itself: only for a pool nothing renders on yet."""
        while True:
            try:
                worker, event = self.events.get_nowait()
            except queue.Empty:
                break
            self._event(worker, event)
        return all(w.warmed for w in self.workers if w.alive)

    def cancel(self):
        """Units in flight stop within a bounce (answered None); prepare() starts the next render."""
        if not self.cancelled:
            self.cancelled, self.cancelled_at = True, time.perf_counter()
            for w in self.workers:
                if w.alive and w.in_flight:
                    w.send(("cancel",))

    def close(self, wait: bool = True):
        """End the workers.  wait=False: without waiting for their ends when every worker is alive
        and holds no unit (engine/pools/transport.py close_all), else as wait=True."""
        clean = not self.outstanding() and all(w.alive for w in self.workers)
        self.cancelled = True
        close_all(self.workers, CLOSE_SECONDS, wait=wait or not clean)

    def stats(self) -> dict:
        return {"worker_python": self.python, "worker_pids": [w.pid for w in self.workers],
                "scenes_prepared": self.builds, "worker_reports": list(self.reports)}

    def warnings(self) -> list:
        return list(self.reports)


# -- the progressive render -----------------------------------------------------------------------
def film_image(film):
    """(height, width, 4) float32 linear RGBA of a frame's film as shown (engine/rendering/frame.py
    FrameFilm.display: exposure, alpha), row 0 = BOTTOM (Blender's order)."""
    shown = film.display()
    rgba = np.ones((film.height, film.width, 4), np.float32)
    rgba[..., :shown.shape[-1]] = shown[::-1]
    rgba[~np.isfinite(rgba)] = 0.0
    return rgba


def relative_error(film):
    """Per-pixel noise: the RMS standard error of the pixel means (the film's variance of the
    mean) relative to the mean, over the pixels that received light (a black background would
    otherwise inflate it by 1/sqrt(lit fraction)); None below two samples in some pixel."""
    if film.count.min() < 2:
        return None
    mean = film.mean()
    lit = mean.sum(axis=-1) > 0
    m = float(mean[lit].mean()) if lit.any() else 0.0
    if not m > 0:
        return None
    return float(np.sqrt(film.variance_of_mean()[lit].mean())) / m


class ViewportRender:
    """The progressive render of the current scene and view on a pool whose prepare() may be
    called again (the viewport's), on a thread of its own.  `pool` is the pool, or `make_pool`
    makes it on that thread (the workers start while the caller goes on).  set_scene / set_view
    restart it and return at once; on_frame() is called (on that thread) after every merged unit."""

    def __init__(self, pool=None, on_frame=None, make_pool=None):
        self.pool, self.make_pool, self.on_frame = pool, make_pool, on_frame
        self.lock = threading.Lock()
        self.wake = threading.Condition(self.lock)
        self.gen = 0                              # the request number: a new scene or view
        self.request = None                       # (gen, scene, settings, target, tag, start_resolution, pixel_size)
        self.target = 1
        self.level = -1                           # of the picture shown (0: coarse, 1: the view)
        self.frame = None                         # the Frame of the picture shown (its plan, stats: diagnostics)
        self.version = 0                          # changes whenever the picture does
        self.error = None
        self.latest = Picture(0, None, 0, None, -1, None)   # the picture shown (snapshot, picture)
        self.gen_started = time.perf_counter()
        self.first_frame_seconds = None           # of the current request, coarse or not
        self.closed = False
        self.thread = threading.Thread(target=self._run, daemon=True, name="viewport render")
        self.thread.start()

    @property
    def pids(self):
        return self.pool.stats().get("worker_pids", []) if self.pool is not None else []

    @property
    def builds(self):
        return self.pool.stats().get("scenes_prepared", 0) if self.pool is not None else 0

    def set_scene(self, scene, settings, target: int, tag=None, start_resolution: int = START_RESOLUTION,
                  pixel_size: int = 1):
        """A new scene (geometry, materials, lights or settings changed): prepared again."""
        target = max(1, int(target))
        self._ask(scene, dataclasses.replace(settings, samples=target), target, tag,
                  max(1, int(start_resolution)), max(1, int(pixel_size)))

    def set_view(self, camera, resolution, tag=None):
        """Only the camera (or the viewport's size) changed: the workers prepare nothing again."""
        _, scene, settings, target, _, start_resolution, pixel_size = self.request
        self._ask(dataclasses.replace(scene, camera=camera, resolution=tuple(resolution)), settings, target, tag,
                  start_resolution, pixel_size)

    def _ask(self, scene, settings, target, tag, start_resolution, pixel_size):
        with self.lock:
            self.gen += 1
            self.request = (self.gen, scene, settings, target, tag, start_resolution, pixel_size)
            self.target = target
            self.level, self.error, self.frame = -1, None, None
            self.version += 1
            self.latest = Picture(self.version, None, 0, None, -1, None, tag)
            self.gen_started, self.first_frame_seconds = time.perf_counter(), None
            self.wake.notify()

    def _run(self):
        done = 0
        while True:
            with self.lock:
                while not self.closed and (self.request is None or self.request[0] == done):
                    self.wake.wait()
                if self.closed:
                    return
                request = self.request
            gen, scene, settings, target, tag, start_resolution, pixel_size = request
            try:
                if self.pool is None:
                    self.pool = self.make_pool()
                    if self.closed:             # closed while the workers started
                        self.pool.close()
                        return
                dividers = frame_dividers(scene.resolution, start_resolution, pixel_size)
                for divider in dividers:
                    level = 1 if divider == dividers[-1] else 0
                    frame_scene = scene if divider == 1 else dataclasses.replace(
                        scene, resolution=coarse_resolution(scene.resolution, divider))
                    if self.gen != gen or not self._frame(gen, level, divider, tag, frame_scene, settings):
                        break
            except Exception as exc:            # noqa: BLE001 - shown in the viewport's header
                with self.lock:
                    if gen == self.gen:
                        self.error = one_line(exc)
                        self.version += 1
                        self.latest = self.latest._replace(version=self.version, error=self.error)
                self._notify()
            done = gen

    def _frame(self, gen, level, divider, tag, scene, settings) -> bool:
        """Render one frame of the request `gen` (level 0: 1 sample); False when a newer request came."""
        from ..rendering.frame import Frame
        from ..rendering.units import await_units
        facts = self.pool.prepare(scene, settings)
        if self.gen != gen:
            return False
        w, h = scene.resolution
        shape = dataclasses.replace(settings, samples=1 if level == 0 else settings.samples,
                                    tile_size=max(8, w, h), noise_target=0.0)
        frame = Frame(scene, shape, facts, "growing")
        pool = frame.scheduled(self.pool)          # caustic photon batches traced once (engine/rendering/photon_passes.py)
        pool.start(frame.units)

        def merge(result):
            frame.add(result)                   # the film is this thread's alone
            if gen != self.gen or level < self.level or frame.film.count.min() == 0:
                return                          # all of it, or nothing
            film = frame.film
            rgba = film_image(film)             # made here, not on the thread that draws
            samples = int(film.count.min()) if level == 1 else 0
            noise = relative_error(film) if level == 1 else None
            with self.lock:
                if gen == self.gen and level >= self.level:
                    self.level, self.frame = level, frame
                    self.version += 1
                    self.latest = Picture(self.version, rgba, samples, noise, level, None, tag, divider)
                    if self.first_frame_seconds is None:
                        self.first_frame_seconds = time.perf_counter() - self.gen_started
            self._notify()

        reason, error = await_units(pool, len(frame.units), merge,
                                    lambda: "restart" if self.gen != gen or self.closed else None, poll=0.02)
        if error is not None:
            raise error
        return reason is None

    def _notify(self):
        if self.on_frame is not None:
            try:
                self.on_frame()
            except Exception:                   # noqa: BLE001 - a redraw request must not stop the render
                pass

    def picture(self) -> Picture:
        """The picture shown (made on the render thread: reading it costs nothing)."""
        with self.lock:
            return self.latest

    def snapshot(self):
        """(version, rgba or None, samples, relative error or None, level, error message) of picture()."""
        return tuple(self.picture()[:6])

    def notice(self):
        """A worker's death of the last few seconds, named (engine/pools/viewport.py ViewportPool.notice), or None."""
        notice = getattr(self.pool, "notice", None)
        return notice() if notice is not None else None

    def converged(self) -> bool:
        shown = self.picture()
        return shown.level == 1 and shown.samples >= self.target

    def close(self):
        """Stop the render and the pool's workers.  Safe to call twice; blocks up to a few
        seconds (the viewport calls it on a thread of its own)."""
        with self.lock:
            if self.closed:
                return
            self.closed = True
            self.wake.notify()
        self.thread.join(timeout=5)
        if self.pool is not None:
            self.pool.close()


if __name__ == "__main__":
    exit_worker(viewport_worker_main(int(sys.argv[1])))
