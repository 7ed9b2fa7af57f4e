"""Progressive viewport rendering in worker processes: interruptible passes over the whole frame.

A viewport worker is ``python -m <tracer package>.pools.viewport PARENT_PID`` (started by
`ViewportWorkers`, never by Blender's UI thread blocking on it).  It keeps one RenderSession (BVH,
lights, effect plan) and renders passes of the current view until a message changes it:

    parent -> worker   ("hello", parent_base)
                       ("scene", gen, scene, settings, target, index, count)   rebuild the session
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
(`ViewportFilm`); frames of an older generation are dropped.
"""
from __future__ import annotations

import os
import pickle
import queue
import signal
import subprocess
import sys
import threading
import time
import traceback
from dataclasses import replace

import numpy as np

from ..core.paths import TRACER_BASE, TRACER_DIR, worker_environment
from .processes import decode, encode, read_frame

COARSE = 4                      # coarse pass: 1/COARSE of the resolution in each direction


# -- the worker -----------------------------------------------------------------------------------
def pass_unit(session, level: int, number: int):
    """The work unit of one pass: the whole frame as one tile, sample `number` (one sample)."""
    from ..rendering.units import Tile, WorkUnit
    width, height = session.scene.resolution
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
    from ..rendering.session import RenderSession
    from .local import die_with_parent
    die_with_parent(parent_pid)
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    inp = sys.stdin.buffer
    hello = read_frame(inp)
    if hello is None:
        return 0
    _, foreign = pickle.loads(hello)
    inbox: queue.Queue = queue.Queue()
    interrupt = threading.Event()

    def read():
        while True:
            data = read_frame(inp)
            inbox.put(("quit",) if data is None else decode(data, foreign))
            interrupt.set()
            if data is None:
                return

    threading.Thread(target=read, daemon=True).start()

    def send(obj):
        out.write(encode(obj))
        out.flush()

    session, job = None, None
    while True:
        idle = session is None or job is None or job.level == 1 and job.next_sample() is None
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
                        session = None
                        session = RenderSession(scene, settings, log=lambda msg: print(msg, file=sys.stderr))
                        session.full_resolution = tuple(scene.resolution)
                        job = ViewJob(gen, scene.resolution, target, index, count)
                        send(("ready", gen, {"accelerator": session.accelerator, "warnings": list(session.warnings),
                                             "build_seconds": session.geometry.build_seconds}))
                    elif m[0] == "view" and session is not None:
                        _, gen, camera, resolution = m
                        camera.validate()
                        session.scene.camera = camera
                        session.full_resolution = tuple(resolution)
                        job = ViewJob(gen, resolution, job.target, job.index, job.count)
                except Exception as exc:        # noqa: BLE001 - shown in the viewport's header
                    session, job = None, None
                    send(("error", m[1], str(exc) if type(exc).__name__ == "SceneError"
                          else f"{type(exc).__name__}: {exc}"))
                    print(traceback.format_exc(), file=sys.stderr)
            continue
        if job.level == 0:
            resolution, number = coarse_resolution(job.resolution), job.index
        else:
            resolution, number = job.resolution, job.next_sample()
        session.scene.resolution = tuple(resolution)
        try:
            result = session.render_unit(pass_unit(session, job.level, number), interrupt)
        except Exception as exc:                # noqa: BLE001
            send(("error", job.gen, f"{type(exc).__name__}: {exc}"))
            print(traceback.format_exc(), file=sys.stderr)
            job = None
            continue
        if result is None:                      # interrupted by a message
            continue
        w, h = resolution
        send(("frame", job.gen, job.level, w, h, result.sum.astype(np.float32), result.sum_sq.astype(np.float32),
              1))
        if job.level == 0:
            job.level = 1
        else:
            job.passes += 1


# -- the parent side ------------------------------------------------------------------------------
class ViewportFilm:
    """The sums of the current generation: a coarse image until the first full-resolution pass."""

    def __init__(self):
        self.gen, self.level, self.size = -1, -1, None
        self.sum = self.sum_sq = None
        self.samples = 0
        self.version = 0

    def reset(self, gen):
        self.gen, self.level, self.size, self.sum, self.sum_sq, self.samples = gen, -1, None, None, None, 0

    def add(self, gen, level, width, height, s, s2, samples) -> bool:
        """Merge a worker's frame; False when it belongs to an older view or a finer level exists."""
        if gen != self.gen or level < self.level:
            return False
        if level > self.level or (width, height) != self.size:
            self.level, self.size, self.samples = level, (width, height), 0
            self.sum = np.zeros((height * width, 3))
            self.sum_sq = np.zeros((height * width, 3))
        self.sum += s
        self.sum_sq += s2
        self.samples += samples
        self.version += 1
        return True

    def image(self):
        """(height, width, 4) float32 linear RGBA, row 0 = BOTTOM (Blender's order), or None."""
        if self.sum is None:
            return None
        w, h = self.size
        rgba = np.ones((h, w, 4), np.float32)
        rgba[..., :3] = (self.sum / self.samples).reshape(h, w, 3)[::-1]
        rgba[~np.isfinite(rgba)] = 0.0
        return rgba

    def relative_error(self):
        """Per-pixel noise: the RMS standard error of the pixel means (sample variance / n) relative
        to the mean, over the pixels that received light (a black background would otherwise inflate
        it by 1/sqrt(lit fraction)); None below two full-resolution samples."""
        if self.sum is None or self.level < 1 or self.samples < 2:
            return None
        n = self.samples
        mean = self.sum / n
        var_of_mean = np.maximum(self.sum_sq / n - mean * mean, 0.0) / (n - 1)
        lit = mean.sum(axis=-1) > 0
        m = float(mean[lit].mean()) if lit.any() else 0.0
        if not m > 0:
            return None
        return float(np.sqrt(var_of_mean[lit].mean())) / m


class ViewportWorkers:
    """Viewport worker processes of `python`: `set_scene` / `set_view` restart accumulation;
    frames are merged on reader threads and `on_frame()` is called after each (any thread)."""

    def __init__(self, python: str, count: int = 1, extra_paths=(), on_frame=None):
        env = worker_environment(extra_paths)
        module = os.path.basename(TRACER_DIR) + ".pools.viewport"
        self.procs = [subprocess.Popen([python, "-m", module, str(os.getpid())], stdin=subprocess.PIPE,
                                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, close_fds=True)
                      for _ in range(max(1, count))]
        self.lock = threading.Lock()
        self.film = ViewportFilm()
        self.gen = 0
        self.target = 1
        self.error = None
        self.facts = None
        self.builds = 0                          # sessions the workers built (a new view builds none)
        self.on_frame = on_frame
        self.started = time.perf_counter()
        self.gen_started = self.started
        self.first_frame_seconds = None          # of the current generation, coarse or not
        self.stderr_tail: list = []
        self.closed = False
        self.outboxes = {p.pid: queue.Queue() for p in self.procs}
        for p in self.procs:
            threading.Thread(target=self._write, args=(p,), daemon=True).start()
            self._send(p, ("hello", TRACER_BASE))
            threading.Thread(target=self._read, args=(p,), daemon=True).start()
            threading.Thread(target=self._read_stderr, args=(p,), daemon=True).start()

    @property
    def pids(self):
        return [p.pid for p in self.procs]

    def _send(self, proc, message):
        """Queue a message: a writer thread pickles and writes it, so the caller (Blender's UI
        thread) never waits for a busy worker's pipe or for pickling a big scene."""
        self.outboxes[proc.pid].put(message)

    def _write(self, proc):
        outbox = self.outboxes[proc.pid]
        while True:
            message = outbox.get()
            if message is None:
                break
            try:
                proc.stdin.write(encode(message))
                proc.stdin.flush()
            except (BrokenPipeError, OSError, ValueError):
                break
        try:
            proc.stdin.close()
        except (OSError, ValueError):
            pass

    def _next_gen(self):
        with self.lock:
            self.gen += 1
            self.film.reset(self.gen)
            self.error = None
            self.gen_started = time.perf_counter()
            self.first_frame_seconds = None
            return self.gen

    def set_scene(self, scene, settings, target: int):
        """A new scene (geometry, materials, lights or settings changed): every worker rebuilds."""
        self.target = int(target)
        settings = replace(settings, samples=max(int(target), 1))
        gen = self._next_gen()
        for i, p in enumerate(self.procs):
            self._send(p, ("scene", gen, scene, settings, self.target, i, len(self.procs)))

    def set_view(self, camera, resolution):
        """Only the camera (or the viewport's size) changed: no rebuild in the workers."""
        gen = self._next_gen()
        for p in self.procs:
            self._send(p, ("view", gen, camera, tuple(resolution)))

    def _read(self, proc):
        foreign = os.path.basename(TRACER_DIR)
        while True:
            try:
                data = read_frame(proc.stdout)
            except (OSError, ValueError):
                data = None
            if data is None:
                break
            message = decode(data, foreign)
            with self.lock:
                if message[0] == "frame":
                    if self.film.add(*message[1:]):
                        if self.first_frame_seconds is None:
                            self.first_frame_seconds = time.perf_counter() - self.gen_started
                    else:
                        continue
                elif message[0] == "error" and message[1] == self.gen:
                    self.error = message[2]
                elif message[0] == "ready":
                    self.facts = message[2]
                    self.builds += 1
            if self.on_frame is not None:
                try:
                    self.on_frame()
                except Exception:               # noqa: BLE001 - a redraw request must not kill the reader
                    pass
        code = proc.poll()
        if not self.closed:
            with self.lock:
                tail = [line for line in self.stderr_tail if line.strip()]
                self.error = (f"viewport render worker (pid {proc.pid}) stopped"
                              + (f" (exit code {code})" if code is not None else "")
                              + (f": {tail[-1]}" if tail else ""))
            if self.on_frame is not None:
                try:
                    self.on_frame()
                except Exception:               # noqa: BLE001
                    pass

    def _read_stderr(self, proc):
        for raw in iter(proc.stderr.readline, b""):
            line = raw.decode("utf-8", "replace").rstrip()
            self.stderr_tail = (self.stderr_tail + [line])[-20:]
            if not line.startswith("warning:"):
                print(f"[viewport worker {proc.pid}] {line}", file=sys.stderr)

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
        for p in self.procs:
            self.outboxes[p.pid].put(None)           # the writer closes stdin: EOF ends the worker
        deadline = time.perf_counter() + 1.0
        for p in self.procs:
            try:
                p.wait(timeout=max(0.0, deadline - time.perf_counter()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


if __name__ == "__main__":
    sys.exit(viewport_worker_main(int(sys.argv[1])))
