"""Render work units on a Dask cluster: `render(..., pool=make_pool("dask:tcp://host:8786"))`.

DaskPool is a pool of engine/pools/protocol.py whose units run as Dask tasks on plain
`dask scheduler` / `dask worker` processes:

* The scene travels once, pickled, inside one task ("tncg15-scene-<id>") that every unit depends on.
  It is a task, not scattered data, so when the worker holding it dies the scheduler recomputes it
  elsewhere (scattered data would be lost with its last holder: the Active Memory Manager keeps one
  copy only).  Each worker process prepares the scene (engine/rendering/session.py PreparedScene:
  validation, BVH, lights) once per render and keeps it in a small per-process cache; prepare()
  has one worker do so first and return its facts (accelerator, effect plan, warnings).
* A unit task carries only the scene task, the unit (as plain values) and the client's engine version.  A
  worker of another engine version refuses the unit with a message; workers are also asked their
  version when the render starts and those that differ get no units.
* The task function travels by value through a small trampoline that imports the engine on the
  worker only, so the scheduler needs nothing of this project (it unpickles every task).
* Results stream back through `distributed.as_completed`; a SIGKILLed worker's units are re-run on
  the others (the scheduler notices the closed connection at once).  A worker that stops answering
  (SIGSTOP, a cut network link) is found by a unit deadline and removed, and no worker left or a
  lost scheduler ends the render with one line that keeps the finished units: engine/pools/dask_watch.py.  Units depend only on (seed,
  pixel, sample), and the film merges each tile's units in order, so the image is bit for bit the
  one the local pool renders.
* cancel(): the futures are cancelled and a running unit sees its task cancelled on the worker
  (checked once per bounce) and stops; close() waits until no unit of this render runs anywhere.
* "dask:local" starts a LocalCluster on this machine for trying it out (a few seconds to
  start; the project's own process pool stays the default).
"""
from __future__ import annotations

import collections
import errno
import os
import pickle
import queue
import re
import signal
import threading
import time
import uuid

from ..core.errors import SceneError, WorkersLost
from ..core.paths import TRACER_DIR
from ..core.version import BUILD_HASH, ENGINE_VERSION, short_build
from . import dask_watch, faults
from .protocol import Pool

CONNECT_SECONDS = 5        # scheduler unreachable: one line within this (docs/command-line.md: within 6 s)
HANDSHAKE_SECONDS = 5      # a port that accepts connections but does not speak Dask: one line within this
POLL_SECONDS = 0.1         # a stop request ends a connection wait within this
WORKERS_SECONDS = 10       # a scheduler without workers
CANCEL_SECONDS = 10        # close() waits at most this for cancelled units to stop on the workers
CLIENT_CLOSE_SECONDS = 2  # the client's own close (a lost scheduler: it gives up after this)
PROBE_SECONDS = 0.5        # ... but gives up when the workers do not answer within this (one is stopped)
GATHER_SECONDS = 0.5       # a finished unit's result is fetched in steps of this (a cancel drops it between steps)
UNIT_RETRIES = 2           # exceptions; worker deaths are counted by the scheduler (allowed-failures)
KEY_PREFIX = "tncg15"


class ClusterError(SceneError):
    """The cluster cannot render: unreachable scheduler, no workers, other engine versions.
    A SceneError so that both command lines print it as one line and exit 2."""


class ClusterLost(ClusterError, WorkersLost):
    """No Dask worker is left, the scheduler was lost, or a unit killed its workers: one line, and
    the frame keeps the finished units (engine/rendering/frame.py) for the command lines to write."""


class ConnectStopped(ClusterError):
    """A stop request (Ctrl-C, Esc: the pool's should_cancel) came while connecting to the scheduler."""


# -- worker side ----------------------------------------------------------------------------------

def call(target: str, *args):
    """Trampoline: import `module:function` where it runs (a worker) and call it.  Pickled by value
    (its module is set to __main__ below), so the scheduler, which unpickles every task, needs no
    copy of this project."""
    import importlib
    module, name = target.split(":")
    return getattr(importlib.import_module(module), name)(*args)


call.__module__ = "__main__"
call.__qualname__ = call.__name__ = "tncg15_call"

_PREPARED: collections.OrderedDict = collections.OrderedDict()   # payload key -> PreparedScene
_PREPARED_KEPT = 2
_PREPARED_LOCK = threading.Lock()


def hold_payload(blob: bytes) -> bytes:
    """The scene task: its result is the pickled (scene, settings)."""
    return blob


def worker_scene(key: str, blob: bytes):
    """This process's PreparedScene for payload `key`, prepared on first use."""
    with _PREPARED_LOCK:
        prepared = _PREPARED.get(key)
        if prepared is None:
            from ..core.allocator import tune_malloc
            from ..rendering.session import PreparedScene
            tune_malloc()
            scene, settings = pickle.loads(blob)
            prepared = PreparedScene(scene, settings, log=lambda *a: None)
            _PREPARED[key] = prepared
            while len(_PREPARED) > _PREPARED_KEPT:
                _PREPARED.popitem(last=False)
        return prepared


def forget_scene(key: str) -> bool:
    with _PREPARED_LOCK:
        return _PREPARED.pop(key, None) is not None


class TaskCancelled:
    """is_set() once the scheduler has cancelled the running task (the client cancelled its
    future): read from the worker's own state, no round trip."""

    def __init__(self):
        try:
            from distributed import get_worker
            self.worker = get_worker()
            self.key = self.worker.get_current_task()
        except (ImportError, ValueError):
            self.worker = None

    def is_set(self) -> bool:
        if self.worker is None:
            return False
        ts = self.worker.state.tasks.get(self.key)
        return ts is None or ts.state == "cancelled"


def worker_address() -> str:
    try:
        from distributed import get_worker
        return get_worker().address
    except (ImportError, ValueError):
        return "a worker"


def check_version(client_version) -> None:
    """client_version: the client's (ENGINE_VERSION, BUILD_HASH) (or its version alone)."""
    version, build = client_version if isinstance(client_version, tuple) else (client_version, None)
    if version != ENGINE_VERSION:
        raise RuntimeError(f"worker {worker_address()} runs engine {ENGINE_VERSION}, this is "
                           f"{version}: refused")
    if build != BUILD_HASH:
        raise RuntimeError(f"worker {worker_address()} runs engine build {short_build(BUILD_HASH)}, this is "
                           f"build {short_build(build)} (another checkout of the tracer): refused")


def prepare_task(blob: bytes, key: str, client_version: str):
    """The TracerFacts of the scene, prepared on this worker (and kept for its units)."""
    check_version(client_version)
    return worker_scene(key, blob).facts()


def plain_unit(unit) -> tuple:
    """A work unit as plain Python values: the scheduler unpickles every task and has no copy of
    the engine, so a unit travels as (index, tile fields, chunk, start, stop, mask, halves, part, parts)."""
    t = unit.tile
    return (unit.index, (t.index, t.x0, t.y0, t.x1, t.y1), unit.chunk, unit.start, unit.stop, unit.mask, unit.halves,
            unit.part, unit.parts)


def unit_from_plain(fields):
    from ..rendering.units import Tile, WorkUnit
    index, tile, chunk, start, stop, mask, halves, part, parts = fields
    return WorkUnit(index, Tile(*tile), chunk, start, stop, mask, halves, part, parts)


def render_unit_task(blob: bytes, key: str, unit: tuple, client_version: str, *photons):
    """A camera unit; `photons`: the PhotonResults of the photon batches it gathers from (the results
    of their tasks, which the scheduler brings to this worker once: engine/rendering/photon_passes.py)."""
    check_version(client_version)
    prepared = worker_scene(key, blob)
    for traced in photons:
        prepared.share_photons(traced.unit.batch, traced.stored)
    return prepared.render_unit(unit_from_plain(unit), TaskCancelled())


def photon_unit_task(blob: bytes, key: str, unit: tuple, client_version: str):
    """A photon batch (engine/rendering/units.py PhotonUnit, as (batch, scheduler)), traced on this worker."""
    from ..rendering.units import PhotonUnit
    check_version(client_version)
    return worker_scene(key, blob).render_unit(PhotonUnit(*unit), TaskCancelled())


def photon_summary(traced):
    """A traced photon batch without its photons: what the client needs (counters, seconds), so the
    photons travel only to the workers whose units gather from them."""
    import dataclasses
    return dataclasses.replace(traced, stored=None)


def engine_version() -> tuple:
    """(ENGINE_VERSION, BUILD_HASH) of this worker's engine (a worker of an older engine: its version alone)."""
    return ENGINE_VERSION, BUILD_HASH


def running_units(dask_worker, prefix):
    """Keys starting with `prefix` that this worker is executing now (for client.run)."""
    return [str(getattr(ts, "key", ts)) for ts in dask_worker.state.executing
            if str(getattr(ts, "key", ts)).startswith(prefix)]


# -- client side -----------------------------------------------------------------------------------

def _quiet_distributed_logs():
    """A refused connection or a lost worker is reported by us in one line; distributed's own log
    lines (tracebacks at WARNING) would bury it."""
    import logging
    for name in ("distributed", "distributed.client", "distributed.comm", "distributed.core",
                 "distributed.worker", "distributed.scheduler", "distributed.nanny"):
        logging.getLogger(name).setLevel(logging.CRITICAL)


def start_local_cluster(workers: int):
    """A LocalCluster of `workers` one-thread processes.  Its processes ignore SIGINT (the
    disposition survives spawn): a terminal's Ctrl-C reaches the whole group and the client
    decides, as with the local pool."""
    from distributed import LocalCluster
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if threading.current_thread() is threading.main_thread() \
        else None
    try:
        # No dashboard, and the scheduler's HTTP endpoint on a free port of this machine only.
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                            dashboard_address=None, scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


ADDRESS = re.compile(r"^(?:(tcp|tls)://)?(\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})$")


def scheduler_address(address: str) -> str:
    """`tcp://HOST:PORT` (or tls://); a bare HOST:PORT means tcp.  ClusterError otherwise."""
    match = ADDRESS.match(address.strip())
    if not match or not 0 < int(match.group(3)) < 65536:
        raise ClusterError(f"not a Dask scheduler address: {address!r} (expected tcp://HOST:PORT, e.g. "
                           f"tcp://192.168.1.10:8786, or 'local')")
    return f"{match.group(1) or 'tcp'}://{match.group(2)}:{match.group(3)}"


def probe_scheduler(address: str, timeout: float = CONNECT_SECONDS, handshake: float | None = None,
                    should_cancel=None) -> None:
    """Return when a Dask scheduler answers at `address` (tcp:// or tls://HOST:PORT); else ClusterError,
    one line naming it: refused until `timeout` (the scheduler may be starting), or a connection that
    is accepted but silent for `handshake` seconds.

    distributed's Client waits for the scheduler's handshake without a timeout (distributed/comm/
    core.py `connect`: `await comm.read()`), so a port that accepts TCP and never speaks Dask would
    hang it.  A scheduler writes its handshake as soon as it accepts a connection, before it reads
    anything, so over tcp:// its first bytes must come within `handshake` seconds.  Over tls:// the
    server waits for the client's hello: only the TCP connection is checked.  Every wait is cut into
    POLL_SECONDS steps: `should_cancel()` true (Ctrl-C, Esc) ends it within one with ConnectStopped."""
    import select
    import socket
    scheme, rest = address.split("://", 1)
    host, _, port = rest.rpartition(":")
    handshake = HANDSHAKE_SECONDS if handshake is None else handshake

    def stop_requested():
        if should_cancel is not None and should_cancel():
            raise ConnectStopped(f"stopped while connecting to the Dask scheduler at {address}")

    def ready(sock, until, writable=False) -> bool:
        """sock readable (writable) before `until`."""
        while True:
            stop_requested()
            left = until - time.monotonic()
            if left <= 0:
                return False
            step = min(POLL_SECONDS, left)
            if any(select.select([], [sock], [], step) if writable else select.select([sock], [], [], step)):
                return True

    try:
        family, kind, proto, _, where = socket.getaddrinfo(host.strip("[]"), int(port), type=socket.SOCK_STREAM)[0]
    except OSError as exc:
        raise ClusterError(f"cannot reach the Dask scheduler at {address}: {exc.strerror or exc}") from None
    deadline = time.monotonic() + timeout
    while True:
        with socket.socket(family, kind, proto) as sock:
            sock.setblocking(False)
            error = sock.connect_ex(where)
            if error in (errno.EINPROGRESS, errno.EWOULDBLOCK):
                if not ready(sock, deadline, writable=True):
                    raise ClusterError(f"cannot reach the Dask scheduler at {address}: no answer to a "
                                       f"connection within {timeout:g} s")
                error = sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
            if error == 0:
                if scheme == "tls":
                    return
                if not ready(sock, time.monotonic() + handshake):
                    raise ClusterError(f"{address} accepts connections but does not answer as a Dask scheduler "
                                       f"(no handshake within {handshake:g} s): is it the scheduler's port?")
                try:
                    if sock.recv(1):
                        return
                except OSError:
                    pass
                raise ClusterError(f"{address} closed the connection without a Dask handshake: "
                                   f"is it the scheduler's port?")
        if time.monotonic() >= deadline:
            raise ClusterError(f"cannot reach the Dask scheduler at {address}: {os.strerror(error)}")
        retry = min(deadline, time.monotonic() + 0.2)        # refused: try again, it may be starting
        while time.monotonic() < retry:
            stop_requested()
            time.sleep(min(POLL_SECONDS, max(0.0, retry - time.monotonic())))


def connect(address: str, timeout: float = CONNECT_SECONDS, should_cancel=None, security=None):
    """A distributed Client for `address`; ClusterError (one line naming it) when unreachable or when
    what answers is not a Dask scheduler (probe_scheduler); ConnectStopped on a stop request.
    tls://: with `security`, else the certificates of engine/pools/dask_tls.py."""
    address = scheduler_address(address)
    try:
        from distributed import Client
    except ImportError as exc:
        raise ClusterError(f"--cluster needs dask and distributed (pip install -r requirements.txt): {exc}") from None
    from .dask_tls import security_for
    security = security or security_for(address)
    _quiet_distributed_logs()
    probe_scheduler(address, timeout, should_cancel=should_cancel)
    try:
        return Client(address, timeout=f"{timeout}s", set_as_default=False, security=security)
    except Exception as exc:          # OSError (timeout, refused), ValueError (bad address), ...
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise ClusterError(f"cannot reach the Dask scheduler at {address}: {reason}") from None


def bounded(fn, seconds: float):
    """fn() on a daemon thread: its value, or None when it has not returned within `seconds` or failed."""
    out = {}

    def run():
        try:
            out["value"] = fn()
        except Exception:                          # noqa: BLE001 - None: no answer
            pass

    thread = threading.Thread(target=run, daemon=True, name="tncg15-dask-probe")
    thread.start()
    thread.join(seconds)
    return out.get("value")


class DaskPool(Pool):
    """The pool of engine/pools/protocol.py over a Dask cluster: its scheduler's `address`, or
    "local" for a LocalCluster of `workers` one-thread processes started here."""
    takes_rounds = False        # start() takes a frame's units once: no stopping rules (engine/rendering/stopping.py)
    resolves_photons = True     # photon units and the camera units that need them in one start() (start)

    def __init__(self, address: str, workers: int = 1, log=None, should_cancel=None):
        """should_cancel: polled while connecting (a stop request ends the wait: ConnectStopped)."""
        self.address = address
        self.log = log or (lambda *a: None)
        self.local_cluster = None
        self.futures, self.unit_of = [], {}
        self.photon_futures = []                  # photon batches' tasks (their results stay on the workers)
        self.payload = None
        self.cancelled = False
        self.fetch_stalled = False    # after a cancel, a result's fetch timed out: later ones are dropped unfetched
        self.finished: queue.Queue = queue.Queue()
        self.collector, self.collector_error = None, None
        self.answered: set = set()                # unit keys already answered (by the watch)
        self.answer_lock = threading.Lock()
        self.reports: list[str] = []              # workers given up, by address and why
        self.prepare_seconds = 0.0
        self.stop_watch = threading.Event()
        # Keys name two task groups (dask groups keys by their words before the hex id): the scene
        # task alone, and the units.  The units' group must not contain the scene task, or the
        # scheduler does not see them as "root-ish" and places them all next to the scene's data
        # on the first worker, leaving work stealing to move them later (one worker idle for a third
        # of the render: docs/performance.md); queued on the scheduler, each goes to the next free worker.
        self.render_id = uuid.uuid4().hex[:12]
        self.unit_prefix = f"{KEY_PREFIX}-unit-{self.render_id}"
        if address == "local":
            _quiet_distributed_logs()
            self.local_cluster = start_local_cluster(max(1, workers))
            from distributed import Client
            self.client = Client(self.local_cluster, set_as_default=False)
        else:
            self.client = connect(address, should_cancel=should_cancel)
        try:
            self.workers = self._matching_workers()
        except BaseException:
            self._shutdown()
            raise
        self.restrict = {} if self.workers is None else {"workers": self.workers, "allow_other_workers": False}
        count = len(self.workers) if self.workers is not None else len(self.client.scheduler_info()["workers"])
        self.describe = f"dask {address} ({count} worker{'s' if count != 1 else ''})"

    def _matching_workers(self):
        """None when every worker runs this engine version; else the list of those that do (the
        others are refused with a message).  ClusterError when none does."""
        try:
            self.client.wait_for_workers(1, timeout=WORKERS_SECONDS)
        except Exception:
            raise ClusterError(f"the Dask scheduler at {self.address} has no workers "
                               f"(start some: dask worker {self.address})") from None
        versions = self.client.run(call, f"{__name__}:engine_version", on_error="return")
        good, refused = [], []
        for worker, identity in sorted(versions.items()):
            if isinstance(identity, BaseException):
                refused.append(f"worker {worker} cannot run the engine ({type(identity).__name__}: {identity}; "
                               f"is the project on its PYTHONPATH?)")
                continue
            version, build = identity if isinstance(identity, tuple) else (identity, None)
            if version != ENGINE_VERSION:
                refused.append(f"worker {worker} runs engine {version}, this is {ENGINE_VERSION}: refused")
            elif build != BUILD_HASH:
                refused.append(f"worker {worker} runs engine build {short_build(build)}, this is build "
                               f"{short_build(BUILD_HASH)} (another checkout of the tracer): refused")
            else:
                good.append(worker)
        if not good:
            raise ClusterError("; ".join(refused) or f"no usable worker at {self.address}")
        for message in refused:
            self.log(f"warning: {message}")
        return None if not refused else good

    # -- the pool protocol ---------------------------------------------------------------------
    def prepare(self, scene, settings):
        """The scene task, and one worker's facts of the prepared scene."""
        blob = pickle.dumps((scene, settings), protocol=pickle.HIGHEST_PROTOCOL)
        payload_key = f"{KEY_PREFIX}-scene-{self.render_id}"
        self.payload = self.client.submit(call, f"{__name__}:hold_payload", blob, key=payload_key, pure=False,
                                          **self.restrict)
        started = time.perf_counter()
        facts = self.client.submit(call, f"{__name__}:prepare_task", self.payload, payload_key, (ENGINE_VERSION, BUILD_HASH),
                                   key=f"{KEY_PREFIX}-facts-{self.render_id}", pure=False, **self.restrict)
        try:
            facts = facts.result()
        except SceneError:
            raise
        except Exception as exc:
            text = " ".join(str(exc).split()) or type(exc).__name__
            raise ClusterError(text if "runs engine" in text else
                               f"the Dask cluster {self.address} could not prepare the scene: {text}") from None
        self.prepare_seconds = time.perf_counter() - started
        for w in facts.warnings:
            self.log(f"warning: {w}")
        return facts

    def start(self, units):
        """The units as tasks.  Photon units (engine/rendering/units.py PhotonUnit) become tasks whose
        results the camera units that gather from their batch take as arguments: each batch is traced
        once, and the scheduler brings its photons to the workers that need them (and traces it again
        should its holder die)."""
        from ..integrators.photons.caustics import batches_of
        from ..rendering.units import PhotonUnit
        photons = {}
        for unit in units:
            if isinstance(unit, PhotonUnit):
                key = f"{self.unit_prefix}-photons-{unit.batch}"
                future = self.client.submit(call, f"{__name__}:photon_unit_task", self.payload, self.payload.key,
                                            (unit.batch, unit.scheduler), (ENGINE_VERSION, BUILD_HASH), key=key,
                                            pure=False, retries=UNIT_RETRIES, **self.restrict)
                photons[unit.batch] = future
                self.photon_futures.append(future)      # held: the camera units' tasks need it
                key = f"{self.unit_prefix}-photonsummary-{unit.batch}"
                future = self.client.submit(call, f"{__name__}:photon_summary", future, key=key, pure=False,
                                            retries=UNIT_RETRIES, **self.restrict)
            else:
                key = f"{self.unit_prefix}-{unit.index}"
                needs = [photons[b] for b in batches_of(unit.start, unit.stop) if b in photons] if photons else []
                future = self.client.submit(call, f"{__name__}:render_unit_task", self.payload, self.payload.key,
                                            plain_unit(unit), (ENGINE_VERSION, BUILD_HASH), *needs, key=key,
                                            pure=False, retries=UNIT_RETRIES, **self.restrict)
            self.futures.append(future)
            self.unit_of[key] = unit
        self.collector = threading.Thread(target=self._collect, name="tncg15-dask-results", daemon=True)
        self.collector.start()
        threading.Thread(target=self._watch, name="tncg15-dask-watch", daemon=True).start()

    def _answer(self, key, answer) -> None:
        """Queue a unit's outcome once (the watch and the results may both answer a unit)."""
        with self.answer_lock:
            if key in self.answered:
                return
            self.answered.add(key)
        self.finished.put(answer)

    def _watch(self):
        """The unit deadline and the workers left (engine/pools/dask_watch.py), until close()."""
        clock = dask_watch.UnitClock(first_extra=faults.DEADLINE_FACTOR * self.prepare_seconds)
        usable_since = time.perf_counter()
        while not self.stop_watch.wait(dask_watch.WATCH_SECONDS):
            try:
                view = self.client.run_on_scheduler(dask_watch.units_on_workers, prefix=self.unit_prefix)
            except Exception:                     # the scheduler is gone: the results say so
                continue
            now = time.perf_counter()
            if self.workers is not None:
                view = {w: keys for w, keys in view.items() if w in self.workers}
            for worker, limit in clock.observe(view, now):
                message = f"Dask worker {worker} stopped answering: no unit finished in {limit:.0f} s (removed)"
                self.reports.append(message)
                self.log(f"warning: {message}")
                try:
                    self.client.run_on_scheduler(dask_watch.drop_worker, address=worker, why="unit-deadline")
                except Exception:
                    pass
            if view.keys() - clock.dropped:
                usable_since = now
            elif now - usable_since > dask_watch.NO_WORKER_SECONDS and not self.cancelled:
                left = [f for f in self.futures if not f.done() and f.key not in self.answered]
                if left:
                    why = "; ".join(self.reports[-1:]) or "the last one left the scheduler"
                    self._answer(left[0].key, (self.unit_of[left[0].key], None, ClusterLost(
                        f"no Dask worker is left at {self.address} ({why})")))
                usable_since = now

    def _collect(self):
        try:
            self._collect_results()
        except BaseException as exc:              # surfaced by next_result on the calling thread
            self.collector_error = exc

    def _collect_results(self):
        from distributed import as_completed
        completed = as_completed(self.futures, loop=self.client.loop)
        for future in completed:
            unit = self.unit_of[future.key]
            if future.status == "lost" and not self.cancelled:
                # Finished, then its result went with a worker the unit deadline removed (a stopped
                # one): the scheduler computes it again, and it completes a second time.
                completed.add(future)
                continue
            try:
                if future.status == "finished":
                    answer = (unit, self._result(future), None)
                elif future.status == "cancelled" and self.cancelled:
                    answer = (unit, None, None)
                else:
                    answer = (unit, None, self._error(unit, future))
            except BaseException as exc:          # CancelledError races, a lost scheduler, ...
                answer = (unit, None, None if self.cancelled else self._error(unit, future, exc))
            self._answer(future.key, answer)

    def _result(self, future):
        """A finished unit's result, or None (dropped) once the render is cancelled while the worker that
        holds it does not answer: a SIGSTOPped worker accepts the connection and never replies, and
        the fetch would wait for it until the scheduler's worker-ttl (300 s), the render's cancel with
        it.  After one such fetch, the cancelled render's other unfetched results are dropped without
        a try (each would cost GATHER_SECONDS).  Not cancelled, it waits on: the unit deadline
        (_watch) removes a worker that finishes nothing, and the scheduler computes its results again."""
        from distributed import TimeoutError as FetchTimeout
        while not (self.cancelled and self.fetch_stalled):
            try:
                return future.result(timeout=GATHER_SECONDS)
            except FetchTimeout:
                if self.cancelled:
                    self.fetch_stalled = True
        return None

    def _error(self, unit, future, exc=None):
        if exc is None:
            try:
                exc = future.exception(timeout=1)
            except BaseException as other:
                exc = other
        text = " ".join(str(exc).split()) if exc is not None else ""
        if isinstance(exc, RuntimeError) and "runs engine" in text:
            return ClusterError(text)
        if future.status == "cancelled" or exc is None or not text:
            text = f"{type(exc).__name__ if exc is not None else 'lost'} (was the scheduler {self.address} stopped?)"
            return ClusterLost(f"unit {unit.index} failed on the Dask cluster {self.address}: {text}")
        if type(exc).__name__ == "KilledWorker" or isinstance(exc, OSError):   # it killed its workers; a lost connection
            return ClusterLost(f"unit {unit.index} failed on the Dask cluster {self.address}: {text}")
        return ClusterError(f"unit {unit.index} failed on the Dask cluster {self.address}: {text}")

    def next_result(self, timeout: float):
        try:
            return self.finished.get(timeout=timeout)
        except queue.Empty:
            if self.collector_error is not None:
                raise ClusterError(f"lost the results from {self.address}: {self.collector_error}") from None
            return None

    def cancel(self):
        if self.cancelled:
            return
        self.cancelled = True
        pending = [f for f in self.futures + self.photon_futures if not f.done()]
        if pending:
            try:
                self.client.cancel(pending)
            except Exception:                      # the scheduler is gone: nothing runs for us
                pass

    def running(self) -> list:
        """Keys of this render's units that some worker is executing now."""
        found = self.client.run(running_units, prefix=self.unit_prefix, on_error="return")
        return [k for keys in found.values() if isinstance(keys, list) for k in keys]

    def close(self):
        """Cancel what is left and wait until no unit of this render runs, but never for a
        worker that does not answer (a stopped one: client.run would wait for it)."""
        self.stop_watch.set()
        try:
            if self.futures and not all(f.done() for f in self.futures):
                self.cancel()
            answering = True
            if self.cancelled:
                deadline = time.monotonic() + CANCEL_SECONDS
                while time.monotonic() < deadline:
                    running = bounded(self.running, PROBE_SECONDS)
                    answering = running is not None
                    if not running:
                        break
                    time.sleep(0.05)
            if self.payload is not None and answering:     # a worker that does not answer is not waited for twice
                key = self.payload.key
                bounded(lambda: self.client.run(call, f"{__name__}:forget_scene", key, on_error="ignore"),
                        PROBE_SECONDS)
        except Exception:
            pass                                   # the cluster went away: nothing left to stop
        finally:
            self._shutdown()

    def stats(self) -> dict:
        return {"worker_reports": list(self.reports)} if self.reports else {}

    def warnings(self) -> list:
        return list(self.reports)

    def _shutdown(self):
        self.futures, self.payload, self.photon_futures = [], None, []
        try:
            self.client.close(timeout=CLIENT_CLOSE_SECONDS)
        except Exception:
            pass
        if self.local_cluster is not None:        # ours to stop; an external scheduler never is
            try:
                self.local_cluster.close(timeout=10)
            except Exception:
                pass


# -- a cluster of real processes on this machine (benchmark, tests) --------------------------------

# Dask settings for render workers: the statistical profiler samples every running thread's stack
# every 10 ms (holding the GIL the NumPy bounce needs) and the monitors tick often; off or slower,
# a unit renders a few per cent faster (bench-cluster against the local pool: docs/performance.md,
# "A Dask cluster against the local pool").
RENDER_WORKER_CONFIG = {
    "DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False",
    "DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL": "1s",
    "DASK_DISTRIBUTED__WORKER__MEMORY__MONITOR_INTERVAL": "1s",
    "DASK_DISTRIBUTED__ADMIN__SYSTEM_MONITOR__INTERVAL": "2s",
}


class ProcessCluster:
    """`dask scheduler` plus `dask worker` processes on 127.0.0.1, as one would start them by hand,
    each in its own process group; close() kills them all.  The scheduler runs without this
    project on its path (it needs none); workers get `pythonpath` (default: this repository).
    tls: {"ca", "cert", "key"} PEM files for a tls:// cluster (engine/pools/dask_tls.py), used by
    the scheduler, the workers and the client alike."""

    def __init__(self, directory, workers: int = 2, timeout: float = 60, tls=None):
        import json
        import os
        import subprocess
        import sys
        from pathlib import Path
        self.directory, self.procs, self.timeout = Path(directory), [], timeout
        self.directory.mkdir(parents=True, exist_ok=True)
        self.bin = Path(sys.executable).parent
        self.repo = Path(TRACER_DIR).resolve().parent
        self._subprocess, self._os = subprocess, os
        self.tls_options, security = [], None
        if tls:
            from distributed.security import Security
            from .dask_tls import process_options
            self.tls_options = process_options(tls["ca"], tls["cert"], tls.get("key"))
            security = Security(tls_ca_file=tls["ca"], tls_client_cert=tls["cert"], tls_client_key=tls.get("key"),
                                require_encryption=True)
        info = self.directory / "scheduler.json"
        try:
            self._spawn(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                         "--dashboard-address", "127.0.0.1:0", "--scheduler-file", str(info)]
                        + (["--protocol", "tls"] + self.tls_options if tls else []), "scheduler", None)
            deadline = time.monotonic() + timeout
            while not (info.exists() and info.stat().st_size):
                if time.monotonic() > deadline or self.procs[0].poll() is not None:
                    raise ClusterError(f"dask scheduler did not start: see {self.directory / 'scheduler.log'}")
                time.sleep(0.05)
            time.sleep(0.05)
            self.address = json.loads(info.read_text())["address"]
            self.client = connect(self.address, timeout=10, security=security)
            for i in range(workers):
                self.add_worker(f"w{i + 1}")
        except BaseException:
            self.close()
            raise

    def _spawn(self, args, name, pythonpath):
        env = {k: v for k, v in self._os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
        env.update(RENDER_WORKER_CONFIG)
        if pythonpath:
            env["PYTHONPATH"] = str(pythonpath)
        with open(self.directory / f"{name}.log", "ab") as log:
            proc = self._subprocess.Popen([str(self.bin / "dask"), *map(str, args)], stdout=log,
                                          stderr=self._subprocess.STDOUT, cwd=self.directory, env=env,
                                          start_new_session=True)
        self.procs.append(proc)
        return proc

    def add_worker(self, name, pythonpath=None, nanny: bool = True):
        """One one-thread worker process (under a nanny that restarts it, unless nanny=False)."""
        before = len(self.client.scheduler_info()["workers"])
        proc = self._spawn(["worker", self.address, "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1",
                            "--name", name] + (["--nworkers", "1"] if nanny else ["--no-nanny"]) + self.tls_options,
                           name, pythonpath or self.repo)
        self.client.wait_for_workers(before + 1, timeout=self.timeout)
        return proc

    def stop(self, proc):
        try:
            self._os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=10)

    def close(self):
        client = getattr(self, "client", None)
        if client is not None:
            try:
                client.close(timeout=5)
            except Exception:
                pass
        for proc in self.procs:
            self.stop(proc)
