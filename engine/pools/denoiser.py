"""The viewport's denoiser: one process of the worker Python that keeps OIDN loaded, and the
denoised view of a progressive render.

`DenoiserProcess` is ``python -m <tracer package>.pools.denoiser PARENT_PID`` over the transport of
engine/pools/transport.py (handshake, dies with its parent): it imports pyoidn once
(engine/film/denoise.py) and answers ("denoise", image) with ("image", denoised) or
("unavailable", one line).  OIDN never loads into the caller's process (Blender's: Debian's 3.4
aborts when it does), and a pyoidn that aborts ends only this process.

`DenoisedView` wraps the viewport's ViewportRender (engine/pools/viewport.py) with the same
surface (snapshot, version, set_scene, set_view, close, ...).  With denoising on (`set_denoise`:
Cycles' Viewport > Denoise and its Start Sample) a thread of its own denoises the picture shown
— colour only: the viewport traces no albedo or normal passes — at the display's pace and not at
every sample: at the start sample, then whenever the view's sample count has doubled and the last
denoise is done, and once more at the target.  snapshot() gives the last denoised picture of the
current view (its sample count: the samples it was made from) until a newer one is ready; the
noisy picture before the start sample, and all of the time when denoising is off or unavailable.
"""
from __future__ import annotations

import os
import queue
import sys
import threading

import numpy as np

from ..core.paths import TRACER_DIR, worker_environment
from ..film.denoise import DenoiserUnavailable
from .transport import WorkerEnd, WorkerProcess

ANSWER_SECONDS = 120.0          # the first answer: imports, OIDN's device, a large viewport
POLL_SECONDS = 0.05             # the denoise thread looks at the render this often


# -- the process ----------------------------------------------------------------------------------
def denoiser_main(parent_pid: int) -> int:
    from ..film import denoise
    end = WorkerEnd(parent_pid)
    if not end.handshake():
        return end.exit_code
    denoise.trust_this_process()
    while True:
        message = end.receive()
        if message is None:
            return 0
        try:
            end.send(("image", denoise.denoise(message[1])))
        except DenoiserUnavailable as exc:
            end.send(("unavailable", str(exc)))
        except Exception as exc:                 # noqa: BLE001 - one line for the viewport's header
            end.send(("error", f"{type(exc).__name__}: {exc}"))


class DenoiserProcess:
    """One denoiser process of `python`; denoise() waits for its answer."""

    def __init__(self, python: str, extra_paths=()):
        self.answers: queue.Queue = queue.Queue()
        self.process = WorkerProcess(python, [os.path.basename(TRACER_DIR) + ".pools.denoiser"],
                                     worker_environment(extra_paths), "denoiser",
                                     on_message=lambda w, m: self.answers.put(m),
                                     on_exit=lambda w, code: self.answers.put(("died", w.why(code))))
        self.dead = None                         # why it ended, once it did

    def denoise(self, image, timeout: float = ANSWER_SECONDS) -> np.ndarray:
        """(h, w, 3) float32 denoised; DenoiserUnavailable (one line) when it cannot."""
        if self.dead:
            raise DenoiserUnavailable(self.dead)
        self.process.send(("denoise", np.ascontiguousarray(image, dtype=np.float32)))
        try:
            kind, value = self.answers.get(timeout=timeout)
        except queue.Empty:
            raise DenoiserUnavailable(f"{self.process.name} did not answer within {timeout:.0f} s") from None
        if kind == "image":
            return value
        if kind == "died":
            self.dead = f"{self.process.name} ended: {value}"
            raise DenoiserUnavailable(self.dead)
        raise DenoiserUnavailable(value)

    def close(self):
        self.process.close()
        self.process.wait(1.0)


# -- the denoised view ----------------------------------------------------------------------------
def due(samples: int, last: int, start: int, target: int) -> bool:
    """Whether a picture of `samples` samples is denoised, the last denoised one having `last`
    (0: none yet for this view): from the start sample on, at each doubling, and at the target."""
    if samples < max(1, start) or samples <= last:
        return False
    return last == 0 or (samples >= 2 * last and last < target) or (samples >= target > last)


class DenoisedView:
    """`render` (a ViewportRender) with its picture denoised when set_denoise(start) turned it on;
    the denoiser process (`make_denoiser()`: a DenoiserProcess) starts at the first denoise."""

    def __init__(self, render, make_denoiser):
        self.render, self.make_denoiser = render, make_denoiser
        self.denoiser = None
        self.start = None                        # Start Sample, None: off
        self.lock = threading.Lock()
        self.shown = None                        # (gen, samples, rgba) of the last denoise
        self.done = 0                            # denoised pictures made, part of `version`
        self.denoise_count = 0
        self.problem = None                      # why the denoiser is unavailable (one line)
        self.closed = False
        self.thread = threading.Thread(target=self._run, daemon=True, name="viewport denoiser")
        self.thread.start()

    def __getattr__(self, name):                 # target, gen, pids, builds, converged, ... of the render
        return getattr(self.render, name)

    @property
    def version(self):
        return self.render.version + self.done   # changes with the render and with each denoised picture

    def set_denoise(self, start):
        """Denoise from sample `start` on (Cycles' Start Sample), or None: off."""
        with self.lock:
            was, self.start = self.start, None if start is None else max(1, int(start))
            if self.start == was:
                return
            if self.start is None:
                self.shown = None
            elif was is None:
                self.problem = None                  # turned on again: try again
            self.done += 1                           # the picture shown changes

    def set_scene(self, *args, **kwargs):
        self.render.set_scene(*args, **kwargs)

    def set_view(self, *args, **kwargs):
        self.render.set_view(*args, **kwargs)

    def note(self) -> str | None:
        """For the viewport's header: "Denoised", or why not."""
        with self.lock:
            if self.start is None:
                return None
            if self.problem:
                return f"Denoise off: {self.problem}"
            return "Denoised" if self.shown is not None and self.shown[0] == self.render.gen else None

    def snapshot(self):
        """ViewportRender.snapshot, with the last denoised picture of this view when there is one."""
        gen = self.render.gen
        version, rgba, samples, noise, level, error = self.render.snapshot()
        version, rgba = self._shown(gen, version, rgba, level)
        return version, rgba, samples, noise, level, error

    def picture(self):
        """ViewportRender.picture (engine/pools/viewport.py Picture: with the view it belongs to),
        denoised as snapshot()."""
        gen = self.render.gen
        picture = self.render.picture()
        version, rgba = self._shown(gen, picture.version, picture.rgba, picture.level)
        return picture._replace(version=version, rgba=rgba)

    def _shown(self, gen, version, rgba, level):
        with self.lock:
            shown = self.shown
            if (shown is not None and self.start is not None and shown[0] == gen == self.render.gen
                    and level == 1 and rgba is not None and shown[2].shape == rgba.shape):
                rgba = shown[2]
            return version + self.done, rgba

    def _run(self):
        last_seen = None
        while not self.closed:
            threading.Event().wait(POLL_SECONDS)
            with self.lock:
                start = self.start
            if start is None or self.problem or self.render.version == last_seen:
                continue
            last_seen = self.render.version
            gen = self.render.gen
            _, rgba, samples, _, level, _ = self.render.snapshot()
            if level != 1 or rgba is None or gen != self.render.gen:
                continue
            with self.lock:
                last = self.shown[1] if self.shown is not None and self.shown[0] == gen else 0
            if not due(samples, last, start, self.render.target):
                continue
            try:
                if self.denoiser is None:
                    self.denoiser = self.make_denoiser()
                out = np.array(rgba)
                out[..., :3] = self.denoiser.denoise(rgba[..., :3])
            except (DenoiserUnavailable, OSError) as exc:
                with self.lock:
                    self.problem, self.done = str(exc), self.done + 1
                continue
            with self.lock:
                if gen == self.render.gen and self.start is not None:
                    self.shown = (gen, samples, out)
                    self.done += 1
                    self.denoise_count += 1
            self._notify()

    def _notify(self):
        on_frame = getattr(self.render, "on_frame", None)
        if on_frame is not None:
            try:
                on_frame()
            except Exception:                    # noqa: BLE001 - a redraw request must not stop the denoiser
                pass

    def close(self):
        self.closed = True
        self.thread.join(timeout=5)
        if self.denoiser is not None:
            self.denoiser.close()
        self.render.close()


if __name__ == "__main__":
    sys.exit(denoiser_main(int(sys.argv[1])))
