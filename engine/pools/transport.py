"""The worker transport: a tracer process of any Python, started and spoken to over its pipes.

Used by the render worker processes (engine/pools/processes.py) and the viewport workers
(engine/pools/viewport.py).  A worker is ``python -m MODULE [ARGS] PARENT_PID`` with the tracer's parent
directory (and any bundled wheels) on PYTHONPATH (engine/core/paths.py worker_environment).

* Frames: a little-endian 8-byte length, then a pickle (protocol 5).  A frame with out-of-band
  buffers (only when the sender asked: encode `views`) has their count in the length's top 24 bits
  (COUNT_SHIFT) and each after the pickle as an 8-byte length and its bytes.  The worker's stdout
  carries only frames (the tracer's own prints go to stderr); stdin carries the parent's frames; EOF
  ends the worker.
* Handshake: the parent's first frame is ("hello", its tracer package, its engine version, its
  build hash); the worker answers ("hello", its engine version, its Python version, its pid, its
  build hash), and a worker of another engine version or build (engine/core/version.py BUILD_HASH:
  another checkout) refuses (one line on stderr naming both, exit code 3).
* Package names: the parent may import the tracer as, say, ``tncg15_mc.tracer`` and the worker as
  ``tracer``; each side maps the other's package name onto its own when it unpickles.
* Stderr: the last lines are kept for the message when a worker dies; lines that are not warnings
  (the parent reports those once) are echoed with the worker's name.
* Close: EOF on stdin, then SIGKILL after a grace period.  A worker dies with its parent (Linux
  prctl PDEATHSIG) and ignores SIGINT (a terminal's Ctrl-C reaches the whole process group: the
  parent decides).  Linux sends PDEATHSIG when the *thread* that started the worker ends, so every
  worker is started from one thread that lives as long as the parent process (spawn()).
"""
from __future__ import annotations

import collections
import ctypes
import io
import os
import pickle
import queue
import signal
import struct
import subprocess
import sys
import threading
import traceback

from ..core.paths import TRACER_BASE, TRACER_DIR
from ..core.version import BUILD_HASH, ENGINE_VERSION, short_build

HEADER = struct.Struct("<Q")
PR_SET_PDEATHSIG = 1
REFUSED = 3                       # the worker's exit code when the engine versions or builds differ
NOT_A_FRAME = 2                   # its exit code when stdin holds something else than the parent's frames
LARGEST_FRAME = 1 << 36           # 64 GiB, far beyond any scene: a longer length is not a frame
OUT_OF_BAND_BYTES = 1 << 20       # encode(views=True): arrays this large are written from where they are
COUNT_SHIFT = 40                  # a frame's first 8 bytes: its pickle's length, its buffer count << 40
LARGEST_COUNT = 1 << 12           # out-of-band buffers of one frame, at most: a larger count is not a frame


class FrameError(Exception):
    """The stream holds something else than this transport's frames (garbage on a worker's stdin)."""


# -- frames ---------------------------------------------------------------------------------------
class _Remap(pickle.Unpickler):
    def __init__(self, data: bytes, foreign: str, own: str, buffers=()):
        super().__init__(io.BytesIO(data), buffers=buffers)
        self.foreign, self.own = foreign, own

    def find_class(self, module, name):
        if self.foreign != self.own and (module == self.foreign or module.startswith(self.foreign + ".")):
            module = self.own + module[len(self.foreign):]
        return super().find_class(module, name)


class Frame:
    """An encoded message: the pieces to write in order (bytes, and views of the arrays sent out of
    band).  bytes(frame) joins them; len(frame) is their size in bytes."""

    __slots__ = ("pieces",)

    def __init__(self, pieces: list):
        self.pieces = pieces

    def write_to(self, stream) -> None:
        for piece in self.pieces:
            stream.write(piece)
        stream.flush()

    def __bytes__(self) -> bytes:
        return b"".join(self.pieces)

    def __len__(self) -> int:
        return sum(memoryview(piece).nbytes for piece in self.pieces)


def encode(obj, views: bool = False) -> Frame:
    """The frame of `obj`.  views: the contiguous arrays of OUT_OF_BAND_BYTES or more go out of
    band (pickle protocol 5), the frame holding views of them instead of copies: a scene's 25 MB
    baked sky was copied twice here (pickled, then joined to its length: 30-40 ms on the parent's
    side of every render) and once more by the worker's unpickler.  The arrays must not change until
    the frame is written (a writer thread writes it later): for the scenes sent to be prepared,
    whose arrays the exporter makes anew for every render and nothing changes in place (engine/pools/
    kept.py compares the next scene with them)."""
    buffers: list = []

    def in_band(buffer) -> bool:
        raw = buffer.raw()
        if raw.nbytes < OUT_OF_BAND_BYTES:
            return True
        buffers.append(raw)
        return False
    data = pickle.dumps(obj, protocol=5, buffer_callback=in_band if views else None)
    pieces = [HEADER.pack(len(data) | len(buffers) << COUNT_SHIFT), data]
    for raw in buffers:
        pieces += [HEADER.pack(raw.nbytes), raw]
    return Frame(pieces)


def send_to_live(workers, message) -> None:
    """`message` to every live worker (WorkerProcess) of `workers`, encoded once."""
    payload = encode(message)
    for w in workers:
        if w.alive:
            w.send(payload)


def _read_length(stream) -> int | None:
    head = stream.read(HEADER.size)
    return HEADER.unpack(head)[0] if len(head) == HEADER.size else None


def _not_a_frame(size: int, limit: int, what: str = "frame length") -> None:
    if size > limit:                      # reading it would be an "out of memory" for a few stray bytes
        raise FrameError(f"a {what} of {size:,} (at most {limit:,}): not a frame")


def read_frame(stream):
    """One frame as (its pickle's bytes, its out-of-band buffers), or None at end of stream.  Each
    buffer is a bytearray of its own, read straight from the stream: the arrays unpickled from it
    use it as it is (writable, as an array pickled in band is)."""
    head = _read_length(stream)
    if head is None:
        return None
    _not_a_frame(head, (LARGEST_COUNT << COUNT_SHIFT) - 1, "frame header")
    size, count = head & ((1 << COUNT_SHIFT) - 1), head >> COUNT_SHIFT
    _not_a_frame(size, LARGEST_FRAME)
    data = stream.read(size)
    if len(data) < size:
        return None
    buffers = []
    for _ in range(count):
        size = _read_length(stream)
        if size is None:
            return None
        _not_a_frame(size, LARGEST_FRAME)
        buffer = bytearray(size)
        if stream.readinto(buffer) < size:
            return None
        buffers.append(buffer)
    return data, buffers


def decode(frame, foreign: str, own: str = TRACER_BASE):
    """The message of a frame read by read_frame, the package `foreign` read as `own`."""
    data, buffers = frame
    return _Remap(data, foreign, own, buffers).load()


# -- the worker's end -----------------------------------------------------------------------------
def die_with_parent(parent_pid: int) -> None:
    """In a worker (a forked one too): SIGKILL when the parent dies (Linux prctl), so a killed render
    leaves no orphan; ignore SIGINT (a terminal's Ctrl-C reaches the whole group: the parent decides)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent_pid:          # the parent died before prctl took effect
        os._exit(1)


def exit_worker(code: int):
    """End a worker process now, with `code`, after its streams are flushed (every frame send()
    wrote is flushed already): no interpreter teardown.  Tearing down an interpreter that loaded
    numba's kernels, Embree and a scene took a worker 0.1-0.2 s (two warm workers closed in
    0.22 s, after a render 0.37 s; with this 0.01 s, 2026-12-05), and a pool for one render
    (F12) used to wait for its workers' ends before the render returned (close_all).  Nothing of a
    worker's needs the teardown: its files (numba's cache, engine/core/table_cache.py) are written
    whole and renamed when they are made."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    os._exit(code)


class WorkerEnd:
    """The pipes as the worker sees them: receive() the parent's messages, send() its own."""

    def __init__(self, parent_pid: int):
        die_with_parent(parent_pid)
        self.out = os.fdopen(os.dup(1), "wb")       # the frames; prints of the tracer go to stderr
        os.dup2(2, 1)
        sys.stdout = sys.stderr
        self.inp = sys.stdin.buffer
        self.foreign = None
        self.exit_code = 0                          # the worker's, when handshake() says False
        self.lock = threading.Lock()

    def handshake(self) -> bool:
        """Read the parent's hello and answer it; False at EOF (exit_code 0), when the engine versions or
        builds differ (REFUSED) or when stdin holds no hello frame (NOT_A_FRAME, one line on stderr)."""
        try:
            frame = read_frame(self.inp)
            if frame is None:
                return False
            _, self.foreign, version, *build = pickle.loads(frame[0], buffers=frame[1])
        except Exception as exc:                    # noqa: BLE001 - any bytes can reach an unpickler
            print(f"error: this worker reads its parent's frames on stdin (engine/pools/transport.py); it got "
                  f"something else: {type(exc).__name__}: {' '.join(str(exc).split())[:200]}", file=sys.stderr)
            self.foreign, self.exit_code = None, NOT_A_FRAME
            return False
        self.exit_code = REFUSED
        build = build[0] if build else None
        self.send(("hello", ENGINE_VERSION, sys.version.split()[0], os.getpid(), BUILD_HASH))
        if version != ENGINE_VERSION:
            print(f"this worker runs engine {ENGINE_VERSION}, the parent {version}: refused", file=sys.stderr)
            return False
        if build != BUILD_HASH:
            print(f"this worker runs engine build {short_build(BUILD_HASH)}, the parent build {short_build(build)} "
                  "(another checkout of the tracer): refused", file=sys.stderr)
            return False
        self.exit_code = 0
        return True

    def receive(self):
        """The parent's next message, or None at EOF."""
        frame = read_frame(self.inp)
        return None if frame is None else decode(frame, self.foreign)

    def send(self, message) -> None:
        with self.lock:
            encode(message).write_to(self.out)


def log_to_stderr(message) -> None:
    """A worker's log: stderr, which the parent shows (warnings excepted, see WorkerProcess)."""
    print(message, file=sys.stderr)


# -- the parent's end -----------------------------------------------------------------------------
_spawner = {"pid": None, "requests": None}
_spawner_lock = threading.Lock()


def _serve_spawns(requests: queue.Queue) -> None:
    while True:
        args, kwargs, answer = requests.get()
        try:
            answer.put((subprocess.Popen(*args, **kwargs), None))
        except BaseException as exc:           # noqa: BLE001 - raised again in the caller's thread
            answer.put((None, exc))


def spawn(*args, **kwargs) -> subprocess.Popen:
    """subprocess.Popen(*args, **kwargs) run by one thread of this process that never ends.  A
    worker asks the kernel for SIGKILL when its parent dies (die_with_parent: prctl PR_SET_PDEATHSIG),
    and for Linux the parent is the *thread* that forked it: a worker started from a thread that then
    ended (the add-on's warm start, mcrt_addon/warm.py; a Blender render job's thread, whose kept
    workers outlive it with Persistent Data) was killed as that thread ended, measured 2026-12-05:
    3 warm starts in 6 lost one or both workers.  The OS error of a failed start is raised here."""
    with _spawner_lock:
        if _spawner["pid"] != os.getpid():     # first use, or a forked child: its own thread
            _spawner["pid"], _spawner["requests"] = os.getpid(), queue.Queue()
            threading.Thread(target=_serve_spawns, args=(_spawner["requests"],), daemon=True,
                             name="tncg15 worker spawner").start()
        requests = _spawner["requests"]
    answer: queue.Queue = queue.Queue(maxsize=1)
    requests.put((args, kwargs, answer))
    proc, error = answer.get()
    if error is not None:
        raise error
    return proc


def describe_exit(code) -> str:
    if code is None:
        return "stopped answering"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with code {code}"


class WorkerProcess:
    """One worker process, `python -m MODULE [ARGS...] PARENT_PID` (`module`: the list MODULE,
    ARGS...), named `label (pid N)`.

    send() queues a message (or a Frame from encode()): a writer thread pickles and writes it,
    so the caller (Blender's UI thread) never waits for a busy worker's pipe or for pickling a big
    scene.  A reader thread checks the worker's hello and hands every later message to
    on_message(worker, message); when the worker's stdout ends, on_exit(worker, exit code or None).
    Both run on the reader thread."""

    def __init__(self, python: str, module: list, env: dict, label: str, on_message, on_exit,
                 tail_lines: int = 30):
        self.proc = spawn([python, "-m", *module, str(os.getpid())], stdin=subprocess.PIPE,
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, close_fds=True)
        self.pid = self.proc.pid
        self.name = f"{label} (pid {self.pid})"
        self.on_message, self.on_exit = on_message, on_exit
        self.stderr_tail = collections.deque(maxlen=tail_lines)
        self.version = self.python_version = None       # from the worker's hello
        self.closed = False
        self.outbox: queue.Queue = queue.Queue()
        self.outbox.put(("hello", TRACER_BASE, ENGINE_VERSION, BUILD_HASH))
        self.stderr_reader = threading.Thread(target=self._read_stderr, daemon=True, name=self.name + " stderr")
        self.stderr_reader.start()
        threading.Thread(target=self._write, daemon=True, name=self.name + " stdin").start()
        threading.Thread(target=self._read, daemon=True, name=self.name).start()

    def send(self, message) -> None:
        """Queue a message (any picklable object, or a Frame from encode())."""
        if not self.closed:
            self.outbox.put(message)

    def _write(self):
        while True:
            message = self.outbox.get()
            if message is None:
                break
            try:
                (message if isinstance(message, Frame) else encode(message)).write_to(self.proc.stdin)
            except (BrokenPipeError, OSError, ValueError):
                break                                   # it died: the reader reports it
        try:
            self.proc.stdin.close()
        except (OSError, ValueError):
            pass

    def _read(self):
        foreign = os.path.basename(TRACER_DIR)
        stream = self.proc.stdout
        try:
            frame = read_frame(stream)
            if frame is not None:
                _, self.version, self.python_version, _, *self.build = decode(frame, foreign)
                while True:
                    frame = read_frame(stream)
                    if frame is None:
                        break
                    self.on_message(self, decode(frame, foreign))
        except Exception:                       # noqa: BLE001 - a frame we cannot read: the worker is lost
            self.stderr_tail.append(traceback.format_exc())
        try:
            code = self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            code = None
        self.stderr_reader.join(timeout=2)      # its last lines say why (why())
        self.on_exit(self, code)

    def _read_stderr(self):
        for raw in iter(self.proc.stderr.readline, b""):
            line = raw.decode("utf-8", "replace").rstrip()
            self.stderr_tail.append(line)
            if line.startswith("warning:"):
                continue                        # the parent reports the prepared scene's warnings once
            print(f"[{self.name}] {line}", file=sys.stderr)

    def why(self, code) -> str:
        """How it ended, with its last line on stderr: "killed by SIGKILL: ..."."""
        tail = [line for line in self.stderr_tail if line.strip()]
        last = tail[-1] if tail else ""
        return describe_exit(code) + (f": {last}" if last else "")

    def signal(self, number) -> None:
        try:
            self.proc.send_signal(number)
        except OSError:
            pass

    def close(self) -> None:
        """EOF after the messages already queued (the worker ends); see wait()."""
        if not self.closed:
            self.closed = True
            self.outbox.put(None)

    def wait(self, timeout: float) -> None:
        """Wait for the end of the process; SIGKILL after `timeout` seconds."""
        try:
            self.proc.wait(timeout=max(0.0, timeout))
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def start_workers(make, count: int, grace: float, fail):
    """`count` workers (at least one) made by make(number), numbered from 1.  When one cannot start
    (no such interpreter, not executable) the started ones are closed (close_all with `grace`)
    and fail(why) is raised: why is the OS's reason."""
    workers = []
    try:
        for i in range(max(1, count)):
            workers.append(make(i + 1))
    except OSError as exc:
        close_all(workers, grace)
        raise fail(exc.strerror or str(exc)) from None
    return workers


def close_all(workers, grace: float, wait: bool = True) -> None:
    """EOF to every worker, then SIGKILL to those still running after `grace` seconds in all.
    wait=False: return after the EOFs; a thread of this process waits for the ends (and kills
    after `grace`).  For workers that hold no unit and end as soon as they read the EOF: a render
    then returns without waiting for its workers' teardown (an interpreter with numba's kernels
    and a scene: 50-120 ms of every F12 on the workers started ahead, docs/performance.md "A
    render's fixed cost")."""
    import time
    workers = list(workers)
    for w in workers:
        w.close()
    deadline = time.perf_counter() + grace

    def reap():
        for w in workers:
            w.wait(deadline - time.perf_counter())
    if wait:
        reap()
    else:
        threading.Thread(target=reap, daemon=True, name="tncg15 worker reaper").start()
