"""engine/pools/transport.py: the frames, the package-name remapping, the version handshake of a
real worker process, how a worker's exit is described, and that a worker outlives the thread that
started it."""
import io
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from engine.core.errors import SceneError
from engine.core.version import ENGINE_VERSION
from engine.pools import transport
from engine.pools.transport import REFUSED, decode, describe_exit, encode, read_frame

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_frames_round_trip_and_end_at_eof():
    stream = io.BytesIO(bytes(encode(("unit", 3, [1.5, 2.5]))) + bytes(encode({"a": None})))
    assert decode(read_frame(stream), "engine") == ("unit", 3, [1.5, 2.5])
    assert decode(read_frame(stream), "engine") == {"a": None}
    assert read_frame(stream) is None                       # EOF: no more frames


def test_a_truncated_frame_is_not_a_message():
    data = bytes(encode(("unit", 3)))
    assert read_frame(io.BytesIO(data[:-2])) is None


def test_the_other_sides_package_name_is_mapped_onto_ours():
    """A worker that imports the tracer as `tracer` (the add-on's zips) sends classes of
    `tracer.core.errors`; the parent that imports it as `engine` reads them as its own."""
    data, buffers = read_frame(io.BytesIO(bytes(encode(SceneError("Material 'x': bad")))))
    assert b"engine.core.errors" in data
    foreign = (data.replace(b"engine.core.errors", b"tracer.core.errors"), buffers)     # same length: a valid pickle
    restored = decode(foreign, "tracer", "engine")
    assert type(restored) is SceneError and str(restored) == "Material 'x': bad"
    with pytest.raises(ModuleNotFoundError):                                 # control: without the map
        decode(foreign, "engine", "engine")


def test_a_worker_of_another_engine_version_refuses_in_one_line():
    proc = subprocess.Popen([sys.executable, "-m", "engine", "worker", str(os.getpid())], cwd=ROOT,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out, err = proc.communicate(bytes(encode(("hello", "engine", "0.0.0-other"))), timeout=120)
    hello = decode(read_frame(io.BytesIO(out)), "engine")
    assert hello[0] == "hello" and hello[1] == ENGINE_VERSION
    assert proc.returncode == REFUSED
    refusals = [line for line in err.decode().splitlines() if "refused" in line]
    assert refusals == [f"this worker runs engine {ENGINE_VERSION}, the parent 0.0.0-other: refused"]


def test_large_arrays_go_out_of_band_and_come_back_equal_and_writable():
    """encode(views=True): arrays of OUT_OF_BAND_BYTES or more are written from where they are, not
    copied into the pickle; read back they equal the sent ones bit for bit (NaN, -0.0, inf, a
    Fortran-ordered one), writable as an array pickled in band is.  Control: without views the
    pickle holds them."""
    import numpy as np
    n = transport.OUT_OF_BAND_BYTES // 8
    big = np.linspace(-1.0, 1.0, n)
    big[:4] = [np.nan, -0.0, np.inf, -np.inf]
    fortran = np.asfortranarray(np.arange(2 * n, dtype=np.float32).reshape(2, n))
    small = np.arange(5.0)
    message = ("prepare", {"big": big, "fortran": fortran, "small": small, "empty": np.zeros((0, 3))})
    frame = encode(message, views=True)
    data, buffers = read_frame(io.BytesIO(bytes(frame)))
    assert len(buffers) == 2 and len(data) < 4096                    # the two large arrays left the pickle
    assert len(frame) == len(bytes(frame))
    _, got = decode((data, buffers), "engine")
    for key, sent in message[1].items():
        assert got[key].dtype == sent.dtype and got[key].shape == sent.shape
        assert got[key].tobytes(order="A") == sent.tobytes(order="A"), key          # the same bits
        assert got[key].flags.writeable
    assert got["fortran"].flags.f_contiguous
    in_band, no_buffers = read_frame(io.BytesIO(bytes(encode(message))))          # control: copied in
    assert no_buffers == [] and len(in_band) > 2 * transport.OUT_OF_BAND_BYTES


def test_a_frame_cut_in_its_out_of_band_buffers_is_not_a_message():
    import numpy as np
    data = bytes(encode(np.ones(transport.OUT_OF_BAND_BYTES // 8), views=True))
    assert read_frame(io.BytesIO(data)) is not None                                 # control: whole
    assert read_frame(io.BytesIO(data[:-1])) is None
    assert read_frame(io.BytesIO(data[:-transport.OUT_OF_BAND_BYTES - 4])) is None  # in a buffer's length


def test_a_length_no_frame_has_is_not_read():
    """Eight stray bytes read as a length would have Python allocate exabytes (a MemoryError)."""
    from engine.pools.transport import FrameError
    with pytest.raises(FrameError, match="not a frame"):
        read_frame(io.BytesIO(b"garbage\n and more"))


@pytest.mark.parametrize("data", [b"garbage\n", pytest.param(b"\x05\x00\x00\x00\x00\x00\x00\x00hello",
                                                             marks=pytest.mark.slow)],   # a worker each: 0.8 s
                         ids=["text", "a frame of no pickle"])
def test_garbage_on_a_workers_stdin_is_one_line_not_out_of_memory(data):
    """Was "error: out of memory (lower the resolution or the threads)" (a length of 7e18 bytes) or an
    UnpicklingError traceback; now one line saying what the worker expects, exit NOT_A_FRAME."""
    from engine.pools.transport import NOT_A_FRAME
    proc = subprocess.run([sys.executable, "-m", "engine", "worker", str(os.getpid())], cwd=ROOT, input=data,
                          capture_output=True, timeout=120)
    lines = proc.stderr.decode().strip().splitlines()
    assert proc.returncode == NOT_A_FRAME and proc.stdout == b""
    assert len(lines) == 1 and "reads its parent's frames on stdin" in lines[0], lines
    assert "out of memory" not in lines[0]


@pytest.mark.parametrize("code, text", [(-9, "killed by SIGKILL"), (-11, "SIGSEGV")])
def test_exit_codes_are_described_by_their_signal(code, text):
    assert text in describe_exit(code)


def test_a_worker_process_of_another_build_is_refused_naming_both(tmp_path, monkeypatch):
    """A worker whose engine differs by one comment (another checkout, the same ENGINE_VERSION)."""
    from engine.core.version import BUILD_HASH
    from engine.pools.processes import SubprocessPool, WorkerError
    from engine.core.settings import RenderSettings as Settings
    from engine.scene.builtin import cornell_scene
    from tests.pools.test_dask_cluster import other_build
    monkeypatch.chdir(other_build(tmp_path))     # `python -m engine` imports the copy in its directory
    pool = SubprocessPool(sys.executable, 1, log=lambda *a: None)
    with pytest.raises(WorkerError) as err:
        pool.prepare(cornell_scene((8, 8)), Settings(samples=1))
    message = str(err.value)
    assert "\n" not in message and "refused" in message, message
    assert f"the parent build {BUILD_HASH[:12]}" in message and "runs engine build" in message, message


def test_a_worker_ends_at_once_with_its_streams_flushed():
    """exit_worker skips the interpreter's teardown (os._exit) but not what the worker wrote: text
    still in stdout's buffer (a pipe: block-buffered) reaches the parent, and the code is kept."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}     # stdout buffered as a worker's
    code = ("import sys; from engine.pools.transport import exit_worker; "
            "sys.stdout.write('last words'); sys.stderr.write('to stderr'); exit_worker(3)")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, timeout=120,
                          env=env)
    assert (proc.returncode, proc.stdout, proc.stderr) == (3, b"last words", b"to stderr")
    control = subprocess.run([sys.executable, "-c", "import os, sys; sys.stdout.write('lost'); os._exit(3)"],
                             capture_output=True, timeout=120, env=env)
    assert (control.returncode, control.stdout) == (3, b"")      # without the flush the text is lost


CHILD = ("import sys; sys.path.insert(0, {root!r}); from engine.pools.transport import die_with_parent; "
         "die_with_parent(int(sys.argv[1])); print('ready', flush=True); sys.stdin.read()")


def started_from_a_thread_that_ends(start):
    """A worker (die_with_parent, then waits for EOF) started by start(argv, **popen) on a thread that
    ends once the worker is ready; returns the process half a second after that thread ended."""
    out = {}

    def run():
        proc = start([sys.executable, "-c", CHILD.format(root=ROOT), str(os.getpid())], stdin=subprocess.PIPE,
                     stdout=subprocess.PIPE)
        proc.stdout.readline()                          # its prctl has been made
        out["proc"] = proc
    thread = threading.Thread(target=run)
    thread.start()
    thread.join(timeout=120)
    time.sleep(0.5)
    return out["proc"]


def test_a_worker_outlives_the_thread_that_started_it():
    """Linux sends PDEATHSIG when the parent *thread* ends: spawn() starts workers from a thread that
    lives as long as this process (the add-on's warm workers are started on a thread that ends)."""
    proc = started_from_a_thread_that_ends(transport.spawn)
    try:
        assert proc.poll() is None                      # alive
    finally:
        proc.stdin.close()
        assert proc.wait(timeout=60) == 0               # ends at EOF
    control = started_from_a_thread_that_ends(subprocess.Popen)
    assert control.wait(timeout=60) == -signal.SIGKILL  # Popen on that thread: killed as it ended


def test_spawn_raises_the_os_error_of_a_failed_start_in_the_callers_thread():
    with pytest.raises(FileNotFoundError):
        transport.spawn(["/nonexistent/python3", "-c", "pass"])
