"""Render worker processes that any Python can host: the tracer outside Blender's interpreter.

A worker is ``python -m <tracer package> worker <parent pid>`` (engine/cli/main.py) with the tracer's
parent directory (and any bundled wheels) on PYTHONPATH.  It speaks length-prefixed pickle frames
on stdin / stdout (the tracer's own prints go to stderr):

    parent -> worker   ("hello", parent_base)                 plain strings: how to read what follows
                       ("session", scene, settings, progressive)   once: the worker builds a RenderSession
                       ("unit", WorkUnit)                      any number
    worker -> parent   ("ready", facts)                        accelerator, effect plan, build time
                       ("result", unit, UnitResult | None)     None: cancelled, dropped whole
                       ("error", unit, traceback text)

SIGUSR1 cancels: the event passed to render_unit is set, so a busy worker stops within a bounce and
answers every unit left with None.  EOF on stdin ends the worker; it also dies with its parent
(prctl PDEATHSIG, engine/pools/local.py).  Classes travel by module name: the parent imports the tracer
as, say, ``tncg15_mc.tracer`` and the worker as ``tracer``, so each side maps the other's package
name onto its own when it unpickles.

`SubprocessWorkers` is the pool (the engine/pools/local.py interface): it starts the workers before the
scene exists (their imports overlap the export), sends the scene once to each, keeps two units in
flight per worker, re-queues the units of a worker that dies (once per unit) and reports it by name.
`RemoteSession` is a RenderSession without geometry: tiles, units and the film here, the facts of
the preparation (accelerator, effect plan) from the workers.
"""
from __future__ import annotations

import collections
import io
import os
import pickle
import queue
import signal
import struct
import subprocess
import sys
import threading
import time
import traceback
from types import SimpleNamespace

from ..rendering.session import RenderSession
from ..core.settings import RenderSettings
from ..core.paths import TRACER_BASE, TRACER_DIR, worker_environment

HEADER = struct.Struct("<Q")
IN_FLIGHT = 2                             # units queued per worker, so none waits for the next (_feed)
START_TIMEOUT = 120.0                     # seconds for imports + scene + BVH before a worker is given up


class WorkerError(RuntimeError):
    """A worker could not start or died; the message names it and says why."""


# -- frames ---------------------------------------------------------------------------------------
class _Remap(pickle.Unpickler):
    def __init__(self, data: bytes, foreign: str, own: str):
        super().__init__(io.BytesIO(data))
        self.foreign, self.own = foreign, own

    def find_class(self, module, name):
        if self.foreign != self.own and (module == self.foreign or module.startswith(self.foreign + ".")):
            module = self.own + module[len(self.foreign):]
        return super().find_class(module, name)


def encode(obj) -> bytes:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    return HEADER.pack(len(data)) + data


def read_frame(stream) -> bytes | None:
    """One frame's bytes, or None at end of stream."""
    head = stream.read(HEADER.size)
    if len(head) < HEADER.size:
        return None
    size = HEADER.unpack(head)[0]
    data = stream.read(size)
    if len(data) < size:
        return None
    return data


def decode(data: bytes, foreign: str, own: str = TRACER_BASE):
    return _Remap(data, foreign, own).load()


# -- the worker -----------------------------------------------------------------------------------
def worker_main(parent_pid: int) -> int:
    """`python -m engine worker PARENT_PID`: serve one render session on stdin / stdout."""
    cancel = threading.Event()
    signal.signal(signal.SIGUSR1, lambda *_: cancel.set())
    from .local import die_with_parent
    die_with_parent(parent_pid)
    out = os.fdopen(os.dup(1), "wb")          # the protocol; prints of the tracer go to stderr
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    inp = sys.stdin.buffer

    def send(obj):
        out.write(encode(obj))
        out.flush()

    hello = read_frame(inp)
    if hello is None:
        return 0
    _, foreign = pickle.loads(hello)
    data = read_frame(inp)
    if data is None:
        return 0
    _, scene, settings, progressive = decode(data, foreign)
    from ..core.allocator import tune_malloc
    tune_malloc()
    session = RenderSession(scene, settings, log=lambda msg: print(msg, file=sys.stderr), progressive=progressive)
    send(("ready", {"pid": os.getpid(), "accelerator": session.accelerator,
                    "accelerator_reason": session.accelerator_reason, "plan": session.plan,
                    "build_seconds": session.geometry.build_seconds, "setup_seconds": session.setup_seconds,
                    "warnings": list(session.warnings), "python": sys.version.split()[0]}))
    while True:
        data = read_frame(inp)
        if data is None:
            return 0
        _, unit = decode(data, foreign)
        try:
            send(("result", unit, session.render_unit(unit, cancel)))
        except Exception:                       # noqa: BLE001 - the parent reports it with the unit
            send(("error", unit, traceback.format_exc()))


# -- the parent side ------------------------------------------------------------------------------


def describe_exit(code) -> str:
    if code is None:
        return "stopped answering"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with code {code}"


class _Worker:
    def __init__(self, number: int, python: str, env: dict, events: queue.Queue):
        self.number, self.events = number, events
        self.proc = subprocess.Popen([python, "-m", os.path.basename(TRACER_DIR), "worker", str(os.getpid())],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     env=env, close_fds=True)
        self.name = f"render worker {number} (pid {self.proc.pid})"
        self.in_flight: list = []
        self.alive, self.ready = True, False
        self.stderr_tail = collections.deque(maxlen=30)
        self.lock = threading.Lock()
        threading.Thread(target=self._read_stdout, daemon=True, name=self.name).start()
        threading.Thread(target=self._read_stderr, daemon=True, name=self.name + " stderr").start()

    def send(self, data: bytes) -> bool:
        try:
            with self.lock:
                self.proc.stdin.write(data)
                self.proc.stdin.flush()
            return True
        except (BrokenPipeError, OSError, ValueError):
            return False

    def _read_stdout(self):
        stream = self.proc.stdout
        try:
            while True:
                data = read_frame(stream)
                if data is None:
                    break
                self.events.put((self, decode(data, os.path.basename(TRACER_DIR))))
        except Exception:                       # noqa: BLE001 - a frame we cannot read: the worker is lost
            self.stderr_tail.append(traceback.format_exc())
        try:
            code = self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            code = None
        self.events.put((self, ("died", code)))

    def _read_stderr(self):
        for raw in iter(self.proc.stderr.readline, b""):
            line = raw.decode("utf-8", "replace").rstrip()
            self.stderr_tail.append(line)
            if line.startswith("warning:"):
                continue                        # the parent reports the session's warnings once
            print(f"[{self.name}] {line}", file=sys.stderr)

    def why(self, code) -> str:
        tail = [line for line in self.stderr_tail if line.strip()]
        last = tail[-1] if tail else ""
        return describe_exit(code) + (f": {last}" if last else "")


class SubprocessWorkers:
    """The pool of engine/pools/local.py over worker processes: start them (`SubprocessWorkers(python,
    count)`), `prepare(scene, settings, progressive)` once, then RenderSession.run drives it."""

    def __init__(self, python: str, count: int, extra_paths=(), log=print):
        self.python, self.log = python, log
        self.events: queue.Queue = queue.Queue()
        env = worker_environment(extra_paths)
        self.workers = [_Worker(i + 1, python, env, self.events) for i in range(max(1, count))]
        self.describe = f"{len(self.workers)} worker process(es) ({python})"
        self.pending: collections.deque = collections.deque()
        self.retried: set = set()
        self.cancelled = False
        self.reports: list[str] = []            # workers that died, by name
        self.facts = None
        self.ready_seconds = None
        self._started = time.perf_counter()
        self._session = None
        self._early: list = []                  # events seen while waiting for "ready"

    # -- preparation ----------------------------------------------------------------------------
    def prepare(self, scene, settings: RenderSettings, progressive: str = "tiles", timeout: float = START_TIMEOUT):
        """Send the scene to every worker; wait for the first to be ready and return its facts."""
        payload = encode(("hello", TRACER_BASE)) + encode(("session", scene, settings, progressive))
        for w in self.workers:
            if not w.send(payload):
                w.alive = False
        deadline = time.perf_counter() + timeout
        while self.facts is None:
            try:
                worker, event = self.events.get(timeout=max(0.01, deadline - time.perf_counter()))
            except queue.Empty:
                self.close()
                raise WorkerError(f"render workers ({self.python}) did not start within {timeout:.0f} s") from None
            if event[0] == "ready":
                worker.ready = True
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
        return self.facts

    # -- the pool interface ---------------------------------------------------------------------
    def start(self, units):
        self.pending.extend(units)
        for w in self.workers:                  # every worker its first unit before any takes a second
            self._feed(w, limit=1)
        for w in self.workers:
            self._feed(w)

    def _feed(self, worker, limit: int = IN_FLIGHT):
        """Send `worker` units until it has `limit` in flight.  A second unit is queued only while
        more units than live workers are pending: a queued unit waits for its worker even when
        another is idle, and a pass of few units (adaptive passes: one per tile still active) then
        ended when the worker holding two big ones did.  Measured on caustic.blend at 96x96 (4
        tiles, 2 workers): a pass lasted 1.36x the longest worker's share under greedy dispatch."""
        alive = sum(w.alive for w in self.workers)
        while (worker.alive and not self.cancelled and self.pending and len(worker.in_flight) < limit
               and (not worker.in_flight or len(self.pending) > alive)):
            unit = self.pending.popleft()
            worker.in_flight.append(unit)
            if not worker.send(encode(("unit", unit))):
                break                            # it died: the "died" event re-queues its units

    def next_result(self, timeout: float):
        if self.cancelled and self.pending:
            return self.pending.popleft(), None, None      # never sent: dropped like a cancelled unit
        if self._early:
            worker, event = self._early.pop(0)
        else:
            try:
                worker, event = self.events.get(timeout=timeout)
            except queue.Empty:
                return None
        kind = event[0]
        if kind == "ready":
            worker.ready = True
            return None
        if kind == "died":
            return self._died(worker, event[1])
        unit = event[1]
        if unit in worker.in_flight:
            worker.in_flight.remove(unit)
        self._feed(worker)
        if kind == "error":
            where = f"tile {unit.tile.index}" if hasattr(unit, "tile") else repr(unit)
            return unit, None, WorkerError(f"{worker.name} failed on {where}:\n{event[2]}")
        return unit, event[2], None

    def _died(self, worker, code):
        worker.alive = False
        lost, worker.in_flight = worker.in_flight, []
        if self.cancelled or self._closing:
            self.pending.extend(lost)           # answered as cancelled by next_result
            return None
        message = f"{worker.name} died: {worker.why(code)}"
        self.reports.append(message)
        self.log(f"warning: {message}")
        survivors = [w for w in self.workers if w.alive]
        again = [u for u in lost if u.index not in self.retried]
        if not survivors or len(again) < len(lost):
            self.pending.extend(lost)
            failed = self.pending.popleft() if self.pending else None
            return failed, None, WorkerError(message + ("; no render worker is left" if not survivors else
                                                        "; its unit had already been retried once"))
        self.retried.update(u.index for u in again)
        self.pending.extendleft(reversed(again))
        for w in survivors:
            self._feed(w)
        return None

    _closing = False

    def cancel(self):
        if self.cancelled:
            return
        self.cancelled = True
        for w in self.workers:
            if w.alive:
                try:
                    w.proc.send_signal(signal.SIGUSR1)
                except OSError:
                    pass

    def close(self):
        self._closing = True
        for w in self.workers:
            try:
                w.proc.stdin.close()
            except OSError:
                pass
        deadline = time.perf_counter() + 2.0
        for w in self.workers:
            try:
                w.proc.wait(timeout=max(0.0, deadline - time.perf_counter()))
            except subprocess.TimeoutExpired:
                w.proc.kill()
                w.proc.wait()


def start_failure(python: str, worker) -> str:
    """Why the first worker could not start, as one sentence naming what to install."""
    text = "\n".join(worker.stderr_tail)
    for name in ("numpy", "embreex"):
        if f"No module named '{name}'" in text:
            return (f"TNCG15 MC: the Python for render workers ({python}) has no {name}: install it "
                    f"({python} -m pip install numpy embreex) or choose another interpreter in the "
                    "add-on's Preferences (Python for render workers)")
    return f"TNCG15 MC: {worker.name} could not start: {worker.why(worker.proc.poll())}"


class RemoteSession(RenderSession):
    """A RenderSession whose units render elsewhere: the scene is validated and cut into units here
    (identically to the workers' sessions); accelerator and effect plan come from a worker."""

    def __init__(self, scene, settings: RenderSettings, facts: dict, progressive: str = "tiles"):
        settings.validate()
        self.scene, self.settings = scene, settings
        self.warnings = list(facts["warnings"])
        self.accelerator, self.accelerator_reason = facts["accelerator"], facts["accelerator_reason"]
        self.plan = facts["plan"]
        self.geometry = SimpleNamespace(build_seconds=facts["build_seconds"])
        self.setup_seconds = facts["setup_seconds"]
        self.cut_frame(progressive)

    def render_unit(self, unit, cancel=None):
        raise RuntimeError("a RemoteSession renders its units in worker processes")


def render_in_workers(scene, settings: RenderSettings, python: str | None = None, workers=None,
                      on_tile=None, should_cancel=None, on_progress=None, log=print, progressive: str = "tiles"):
    """Render `scene` on worker processes (started here unless `workers`, a SubprocessWorkers that
    is not prepared yet, is given).  The RenderResult's stats add the workers and the start time."""
    settings = settings or RenderSettings()
    if workers is None:
        workers = SubprocessWorkers(python or sys.executable, settings.resolved_threads(), log=log)
    try:
        facts = workers.prepare(scene, settings, progressive)
    except BaseException:
        workers.close()
        raise
    session = RemoteSession(scene, settings, facts, progressive)
    for w in session.warnings:
        log(f"warning: {w}")
    width, height = scene.resolution
    log(f"{session.settings.samples} spp, {width}x{height}, {len(session.units)} work units on {workers.describe}, "
        f"accelerator {session.accelerator} ({session.accelerator_reason})")
    result = session.run(workers, on_tile=on_tile, should_cancel=should_cancel, on_progress=on_progress)
    result.stats["workers_ready_seconds"] = workers.ready_seconds
    result.stats["worker_python"] = workers.python
    result.stats["worker_python_version"] = facts.get("python")
    result.stats["worker_reports"] = list(workers.reports)
    result.warnings = list(result.warnings) + list(workers.reports)
    return result
