"""Progressive viewport rendering in worker processes: interruptible passes over the whole frame.

A viewport worker is ``python -m <tracer package>.pools.viewport PARENT_PID`` (started by
`ViewportWorkers`, never by Blender's UI thread blocking on it), spoken to over the transport of
engine/pools/transport.py.  It keeps one PreparedScene (engine/rendering/session.py: BVH, lights,
effect plan) and renders passes of the current view until a message changes it:

    parent -> worker   ("scene", gen, scene, settings, target, index, count)   prepare the scene again
                       ("view", gen, camera, resolution)                       new camera only: no rebuild
    worker -> parent   ("ready", gen, facts)
                       ("frame", gen, level, width, height, sum, sum_sq, samples)   level 0: coarse
                       ("error", gen, message)

Every message interrupts the pass in progress (the tracer polls its cancel event between
batches), so an edit restarts accumulation within a bounce.  Pass 0 is a coarse pass at
1/COARSE of the resolution (1 sample, large pixels, shown within a fraction of a second); then
worker `index` of `count` renders sample numbers index, index + count, ... of the full frame, one
per pass, until `target` samples exist.  With the Sobol' sampler a sample number gives the same
random numbers whatever the worker, so the merged image is the image of a final render of that
view with `target` samples.  The parent sums the frames of the current generation
(`ViewportFilm`, over the film of engine/film/accumulator.py); frames of an older generation are
dropped.  The viewport's passes are one sample of the whole frame each (render passes, the
stopping rules' rounds and the pools' units are other things).
"""
from __future__ import annotations

import os
import queue
import sys
import threading
import time
import traceback
from dataclasses import replace

import numpy as np

from ..core.paths import TRACER_DIR, worker_environment
from ..film.accumulator import Film
from .transport import WorkerEnd, WorkerProcess, close_all, log_to_stderr

COARSE = 4                      # coarse pass: 1/COARSE of the resolution in each direction


# -- the worker -----------------------------------------------------------------------------------
def pass_unit(prepared, number: int):
    """The work unit of one pass: the whole frame as one tile, sample `number` (one sample)."""
    from ..rendering.units import Tile, WorkUnit
    width, height = prepared.scene.resolution
    return WorkUnit(number, Tile(0, 0, 0, width, height), number, number, number + 1)


def coarse_resolution(resolution, factor: int = COARSE):
    w, h = resolution
    return max(1, -(-w // factor)), max(1, -(-h // factor))


class ViewJob:
    """What the worker renders now: its generation, view, resolution and next pass."""

    def __init__(self, gen, resolution, target, index, count):
        self.gen, self.resolution, self.target, self.index, self.count = gen, tuple(resolution), target, index, count
        self.level, self.passes = 0, 0

    def next_sample(self):
        """The next full-resolution sample number of this worker, or None when `target` is reached."""
        number = self.passes * self.count + self.index
        return number if number < self.target else None


def viewport_worker_main(parent_pid: int) -> int:
    from ..rendering.session import PreparedScene
    end = WorkerEnd(parent_pid)
    if not end.handshake():
        return 0
    inbox: queue.Queue = queue.Queue()
    interrupt = threading.Event()

    def read():
        while True:
            message = end.receive()
            inbox.put(("quit",) if message is None else message)
            interrupt.set()
            if message is None:
                return

    threading.Thread(target=read, daemon=True).start()
    send = end.send
    prepared, job = None, None
    while True:
        idle = prepared is None or job is None or job.level == 1 and job.next_sample() is None
        try:
            message = inbox.get(block=idle)
        except queue.Empty:
            message = None
        if message is not None:
            interrupt.clear()
            messages = [message]
            while not inbox.empty():
                messages.append(inbox.get_nowait())
            for m in messages:
                if m[0] == "quit":
                    return 0
                try:
                    if m[0] == "scene":
                        _, gen, scene, settings, target, index, count = m
                        prepared = None
                        prepared = PreparedScene(scene, settings, log=log_to_stderr)
                        job = ViewJob(gen, scene.resolution, target, index, count)
                        send(("ready", gen, prepared.facts()))
                    elif m[0] == "view" and prepared is not None:
                        _, gen, camera, resolution = m
                        camera.validate()
                        prepared.scene.camera = camera
                        job = ViewJob(gen, resolution, job.target, job.index, job.count)
                except Exception as exc:        # noqa: BLE001 - shown in the viewport's header
                    prepared, job = None, None
                    send(("error", m[1], str(exc) if type(exc).__name__ == "SceneError"
                          else f"{type(exc).__name__}: {exc}"))
                    print(traceback.format_exc(), file=sys.stderr)
            continue
        if job.level == 0:
            resolution, number = coarse_resolution(job.resolution), job.index
        else:
            resolution, number = job.resolution, job.next_sample()
        prepared.scene.resolution = tuple(resolution)
        try:
            result = prepared.render_unit(pass_unit(prepared, number), interrupt)
        except Exception as exc:                # noqa: BLE001
            send(("error", job.gen, f"{type(exc).__name__}: {exc}"))
            print(traceback.format_exc(), file=sys.stderr)
            job = None
            continue
        if result is None:                      # interrupted by a message
            continue
        w, h = resolution
        send(("frame", job.gen, job.level, w, h, result.sum.astype(np.float32), result.sum_sq.astype(np.float32), 1))
        if job.level == 0:
            job.level = 1
        else:
            job.passes += 1


# -- the parent side ------------------------------------------------------------------------------
class ViewportFilm:
    """The sums of the current generation: a coarse image until the first full-resolution pass."""

    def __init__(self):
        self.gen, self.level, self.film = -1, -1, None
        self.samples = 0
        self.version = 0

    def reset(self, gen):
        self.gen, self.level, self.film, self.samples = gen, -1, None, 0

    @property
    def size(self):
        return None if self.film is None else (self.film.width, self.film.height)

    def add(self, gen, level, width, height, s, s2, samples) -> bool:
        """Merge a worker's frame; False when it belongs to an older view or a finer level exists."""
        if gen != self.gen or level < self.level:
            return False
        if level > self.level or (width, height) != self.size:
            self.level, self.film, self.samples = level, Film(width, height), 0
        self.film.add_sums(0, 0, s.reshape(height, width, 3), s2.reshape(height, width, 3), samples)
        self.samples += samples
        self.version += 1
        return True

    def image(self):
        """(height, width, 4) float32 linear RGBA, row 0 = BOTTOM (Blender's order), or None."""
        if self.film is None:
            return None
        rgba = np.ones((self.film.height, self.film.width, 4), np.float32)
        rgba[..., :3] = self.film.mean()[::-1]
        rgba[~np.isfinite(rgba)] = 0.0
        return rgba

    def relative_error(self):
        """Per-pixel noise: the RMS standard error of the pixel means (the film's variance of the
        mean) relative to the mean, over the pixels that received light (a black background would
        otherwise inflate it by 1/sqrt(lit fraction)); None below two full-resolution samples."""
        if self.film is None or self.level < 1 or self.samples < 2:
            return None
        mean = self.film.mean()
        lit = mean.sum(axis=-1) > 0
        m = float(mean[lit].mean()) if lit.any() else 0.0
        if not m > 0:
            return None
        return float(np.sqrt(self.film.variance_of_mean()[lit].mean())) / m


class ViewportWorkers:
    """Viewport worker processes of `python`: `set_scene` / `set_view` restart accumulation;
    frames are merged on reader threads and `on_frame()` is called after each (any thread)."""

    CLOSE_SECONDS = 1.0          # EOF, then SIGKILL

    def __init__(self, python: str, count: int = 1, extra_paths=(), on_frame=None):
        env = worker_environment(extra_paths)
        module = [os.path.basename(TRACER_DIR) + ".pools.viewport"]
        self.lock = threading.Lock()
        self.film = ViewportFilm()
        self.gen = 0
        self.target = 1
        self.error = None
        self.facts = None
        self.builds = 0                          # scenes the workers prepared (a new view prepares none)
        self.on_frame = on_frame
        self.started = time.perf_counter()
        self.gen_started = self.started
        self.first_frame_seconds = None          # of the current generation, coarse or not
        self.closed = False
        self.procs = [WorkerProcess(python, module, env, "viewport worker", self._message, self._exited,
                                    tail_lines=20) for _ in range(max(1, count))]

    @property
    def pids(self):
        return [p.pid for p in self.procs]

    def _next_gen(self):
        with self.lock:
            self.gen += 1
            self.film.reset(self.gen)
            self.error = None
            self.gen_started = time.perf_counter()
            self.first_frame_seconds = None
            return self.gen

    def set_scene(self, scene, settings, target: int):
        """A new scene (geometry, materials, lights or settings changed): every worker prepares it."""
        self.target = int(target)
        settings = replace(settings, samples=max(int(target), 1))
        gen = self._next_gen()
        for i, p in enumerate(self.procs):
            p.send(("scene", gen, scene, settings, self.target, i, len(self.procs)))

    def set_view(self, camera, resolution):
        """Only the camera (or the viewport's size) changed: the workers prepare nothing again."""
        gen = self._next_gen()
        for p in self.procs:
            p.send(("view", gen, camera, tuple(resolution)))

    def _message(self, worker, message):
        with self.lock:
            if message[0] == "frame":
                if not self.film.add(*message[1:]):
                    return
                if self.first_frame_seconds is None:
                    self.first_frame_seconds = time.perf_counter() - self.gen_started
            elif message[0] == "error" and message[1] == self.gen:
                self.error = message[2]
            elif message[0] == "ready":
                self.facts = message[2]
                self.builds += 1
        self._notify()

    def _exited(self, worker, code):
        if self.closed:
            return
        with self.lock:
            tail = [line for line in worker.stderr_tail if line.strip()]
            self.error = (f"viewport render worker (pid {worker.pid}) stopped"
                          + (f" (exit code {code})" if code is not None else "")
                          + (f": {tail[-1]}" if tail else ""))
        self._notify()

    def _notify(self):
        if self.on_frame is not None:
            try:
                self.on_frame()
            except Exception:               # noqa: BLE001 - a redraw request must not kill the reader
                pass

    def snapshot(self):
        """(version, rgba or None, samples, relative error or None, level, error message)."""
        with self.lock:
            f = self.film
            samples = f.samples if f.level >= 1 else 0
            return f.version, f.image(), samples, f.relative_error(), f.level, self.error

    def converged(self) -> bool:
        with self.lock:
            return self.film.level >= 1 and self.film.samples >= self.target

    def close(self):
        """Stop every worker: EOF, then SIGKILL after a second.  Safe to call twice."""
        if self.closed:
            return
        self.closed = True
        close_all(self.procs, self.CLOSE_SECONDS)


if __name__ == "__main__":
    sys.exit(viewport_worker_main(int(sys.argv[1])))
