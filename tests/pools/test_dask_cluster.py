"""Rendering on a Dask cluster (engine/pools/dask_cluster.py) with real `dask scheduler` / `dask worker`
processes on 127.0.0.1: the same image as the local pool bit for bit, a SIGKILLed worker, a
cancelled render, an unreachable scheduler, a worker of another engine version, Ctrl-C."""
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from engine import RenderSettings, render                     # noqa: E402
from engine.pools.dask_cluster import ClusterError, ProcessCluster, running_units  # noqa: E402
from engine.pools.spec import make_pool  # noqa: E402
from engine.scene.builtin import cornell_scene  # noqa: E402
from engine.core.version import ENGINE_VERSION  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
SILENT = dict(log=lambda *a: None)


def dask(address, workers=2, log=SILENT["log"]):
    """The pool of the Dask scheduler at `address` (engine/pools/spec.py)."""
    return make_pool(f"dask:{address}", workers, log=log)


def _env(pythonpath=None):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    if pythonpath:
        env["PYTHONPATH"] = str(pythonpath)
    return env


class Cluster(ProcessCluster):
    """The engine's process cluster (each process in its own group, all SIGKILLed at the end)."""

    def worker_pids(self) -> dict:
        return self.client.run(os.getpid)

    def running(self) -> list:
        found = self.client.run(running_units, prefix="tncg15")
        return [k for keys in found.values() for k in keys]


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    c = Cluster(tmp_path_factory.mktemp("dask"), workers=2)
    try:
        yield c
    finally:
        c.close()


SCENE = dict(resolution=(96, 64))
SETTINGS = dict(samples=24, tile_size=32, seed=11)


def test_cluster_render_is_bit_for_bit_the_local_one(cluster):
    """Determinism: 1 worker, 2 local processes and the 2-worker cluster give the same image."""
    one = render(cornell_scene(**SCENE), RenderSettings(threads=1, **SETTINGS), **SILENT)
    two = render(cornell_scene(**SCENE), RenderSettings(threads=2, parallelism="processes", **SETTINGS), **SILENT)
    on_dask = render(cornell_scene(**SCENE), RenderSettings(threads=2, **SETTINGS), pool=dask(cluster.address),
                     **SILENT)
    assert on_dask.stats["parallelism"] == f"dask {cluster.address} (2 workers)"
    assert on_dask.stats["units_done"] == on_dask.stats["units"] > 2
    assert on_dask.stats["accelerator_reason"] == one.stats["accelerator_reason"]     # a worker's own
    assert on_dask.stats["effects_reason"] == one.stats["effects_reason"]
    assert np.array_equal(one.image, two.image)
    assert np.array_equal(on_dask.image, one.image)
    assert np.array_equal(on_dask.variance, one.variance)
    assert on_dask.image.mean() > 0.05
    assert cluster.running() == []


def unit_placement(dask_scheduler):
    """For each task of a render's units: (key, root-ish, state) as the scheduler sees it."""
    return [(str(key), dask_scheduler.is_rootish(ts), ts.state) for key, ts in dask_scheduler.tasks.items()
            if str(key).startswith("tncg15-unit-")]


unit_placement.__module__ = "__main__"       # pickled by value: the scheduler has no copy of the tests


@pytest.mark.slow          # 2.5 s; the cluster in `make test`: test_cluster_render_is_bit_for_bit_the_local_one
def test_units_queue_on_the_scheduler_for_the_next_free_worker(cluster):
    """The units must be "root-ish" to Dask: queued on the scheduler and handed to whichever worker
    is free.  Otherwise (e.g. scene task and units in one task group) they are all placed at once
    on the worker holding the scene, and the other worker idles once it has run what stealing
    moved to it (a 2-worker render took 1.2-1.35x the local pool's time; 1.05x with queuing)."""
    seen = []

    def look(*tile):
        if not seen:
            seen.append(cluster.client.run_on_scheduler(unit_placement))

    result = render(cornell_scene((128, 128)), RenderSettings(samples=64, tile_size=32, seed=3),
                    pool=dask(cluster.address), on_tile=look, **SILENT)
    assert result.stats["units_done"] == result.stats["units"] >= 16
    units = seen[0]
    assert units and all(rootish for _, rootish, _ in units)
    assert any(state == "queued" for _, _, state in units)          # still waiting for a free worker


@pytest.mark.slow   # a killed worker's units rendered elsewhere: tests/pools/test_processes.py (worker processes)
def test_a_worker_killed_mid_render_changes_nothing(cluster):
    scene, settings = cornell_scene((128, 128)), RenderSettings(samples=64, tile_size=32, seed=4)
    reference = render(scene, settings, **SILENT)
    pids = cluster.worker_pids()
    victim = sorted(pids.values())[0]
    killed = []

    def kill_once(*tile):
        if not killed:
            os.kill(victim, signal.SIGKILL)
            killed.append(time.monotonic())

    result = render(cornell_scene((128, 128)), settings, pool=dask(cluster.address), on_tile=kill_once, **SILENT)
    assert killed and result.stats["units_done"] == result.stats["units"] >= 16
    assert not result.cancelled
    assert np.array_equal(result.image, reference.image)
    with pytest.raises(ProcessLookupError):
        os.kill(victim, 0)
    cluster.client.wait_for_workers(2, timeout=30)                   # the nanny restarted it


def test_a_cancelled_render_leaves_no_unit_running(cluster):
    progress = []
    result = render(cornell_scene((128, 128)), RenderSettings(samples=256, tile_size=32, seed=2),
                    pool=dask(cluster.address), on_progress=lambda f, m: progress.append(f),
                    should_cancel=lambda: len(progress) >= 1, progressive="frame", **SILENT)
    assert result.cancelled and 1 <= result.stats["units_done"] < result.stats["units"]
    assert result.image.mean() > 0                                   # the finished unit is kept
    assert cluster.running() == []                                   # close() waited for the workers


@pytest.mark.slow          # waits out a connect timeout (about 5 s)
def test_unreachable_scheduler_is_one_line_before_dasks_own_timeout(tmp_path):
    """Refused after CONNECT_SECONDS (5 s), not after distributed's default connect timeout of 30 s
    (distributed.comm.timeouts.connect): 25 s leaves room for starting Python and importing Dask on a
    loaded machine (9.8 s measured under a load of 13 on 2 cores, 5.5 s under 5)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]                                    # closed again: nobody listens
    start = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "engine", "render", "--resolution", "16", "16", "--quiet",
                           "-o", str(tmp_path / "a.exr"), "--cluster", f"tcp://127.0.0.1:{port}"],
                          cwd=REPO, env=_env(REPO), capture_output=True, text=True, timeout=60)
    assert time.monotonic() - start < 25
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and f"tcp://127.0.0.1:{port}" in lines[0] and lines[0].startswith("python -m engine: error:")
    assert not (tmp_path / "a.exr").exists()


def test_a_bad_address_is_one_line():
    with pytest.raises(ClusterError, match="not a Dask scheduler address"):
        dask("http//nowhere")


def other_engine(tmp: Path, version: str) -> Path:
    """A copy of the engine package that calls itself `version`."""
    shutil.copytree(REPO / "engine", tmp / "engine", ignore=shutil.ignore_patterns("__pycache__"))
    session = tmp / "engine" / "core" / "version.py"
    text = session.read_text()
    assert f'ENGINE_VERSION = "{ENGINE_VERSION}"' in text
    session.write_text(text.replace(f'ENGINE_VERSION = "{ENGINE_VERSION}"', f'ENGINE_VERSION = "{version}"'))
    return tmp


@pytest.mark.slow          # 2.2 s
def test_a_worker_of_another_engine_version_is_refused(cluster, tmp_path):
    """Alone it refuses the render with a message; next to good workers it gets no units."""
    old = other_engine(tmp_path, "0.0.9")
    lonely = Cluster(tmp_path / "lonely", workers=0)
    try:
        lonely.add_worker("old", pythonpath=old, nanny=False)
        with pytest.raises(ClusterError, match=r"worker tcp://127\.0\.0\.1:\d+ runs engine 0\.0\.9, this is "
                                                + ENGINE_VERSION.replace(".", r"\.")):
            render(cornell_scene((16, 16)), RenderSettings(samples=1), pool=dask(lonely.address), **SILENT)
    finally:
        lonely.close()
    proc = cluster.add_worker("old", pythonpath=old, nanny=False)
    try:
        messages = []
        result = render(cornell_scene(**SCENE), RenderSettings(**SETTINGS),
                        pool=dask(cluster.address, log=messages.append), log=messages.append)
        assert any("runs engine 0.0.9" in m and "refused" in m for m in messages)
        assert result.stats["parallelism"] == f"dask {cluster.address} (2 workers)"
        assert np.array_equal(result.image, render(cornell_scene(**SCENE), RenderSettings(**SETTINGS), **SILENT).image)
    finally:
        cluster.stop(proc)


def other_build(tmp: Path) -> Path:
    """A copy of the engine of the same ENGINE_VERSION that differs by one comment: another checkout."""
    copy = other_engine(tmp, ENGINE_VERSION)
    version = copy / "engine" / "core" / "version.py"
    version.write_text(version.read_text() + "# another checkout\n")
    return copy


def test_a_worker_of_another_build_of_the_same_version_is_refused(tmp_path):
    from engine.core.version import BUILD_HASH
    lonely = Cluster(tmp_path / "lonely", workers=0)
    try:
        lonely.add_worker("other", pythonpath=other_build(tmp_path), nanny=False)
        with pytest.raises(ClusterError, match=r"worker tcp://127\.0\.0\.1:\d+ runs engine build [0-9a-f]{12}, "
                                                f"this is build {BUILD_HASH[:12]} \\(another checkout"):
            render(cornell_scene((16, 16)), RenderSettings(samples=1), pool=dask(lonely.address), **SILENT)
    finally:
        lonely.close()


def test_a_unit_checks_the_engine_build_on_the_worker():
    from engine.pools.dask_cluster import render_unit_task
    with pytest.raises(RuntimeError, match="runs engine build [0-9a-f]{12}, this is build 0123456789ab"):
        render_unit_task(b"", "key", 0, (ENGINE_VERSION, "0123456789abcdef"))


def test_a_unit_checks_the_engine_version_on_the_worker():
    from engine.pools.dask_cluster import render_unit_task
    with pytest.raises(RuntimeError, match=f"runs engine {ENGINE_VERSION}, this is 9.9.9: refused"):
        render_unit_task(b"", "key", 0, "9.9.9")


def test_ctrl_c_stops_like_esc_and_writes_the_finished_work(cluster, tmp_path):
    out = tmp_path / "stopped.exr"
    proc = subprocess.Popen([sys.executable, "-m", "engine", "render", "--resolution", "128", "128",
                             "--samples", "256", "--tile-size", "32", "-o", str(out), "--cluster", cluster.address],
                            cwd=REPO, env=_env(REPO), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    seen = threading.Event()
    err = []

    def read():
        for chunk in iter(lambda: proc.stderr.read1(4096), b""):
            err.append(chunk)
            if re.search(rb"Sample [1-9]\d*/", b"".join(err)):      # a unit merged: stop now
                seen.set()

    threading.Thread(target=read, daemon=True).start()
    try:
        assert seen.wait(60), b"".join(err).decode()
        proc.send_signal(signal.SIGINT)
        stdout = proc.stdout.read()
        proc.wait(timeout=60)
    finally:
        proc.kill()
    text = b"".join(err).decode()
    assert proc.returncode == 130, text
    assert "stopped by SIGINT" in text and out.exists()
    assert "stopped early" in stdout.decode()
    assert cluster.running() == []


@pytest.mark.slow   # cluster = local pool, bit for bit: test_cluster_render_is_bit_for_bit_the_local_one, tests/addon/test_workers.py
def test_cli_local_cluster_matches_the_local_pool(tmp_path):
    """`--cluster local` starts a LocalCluster here (spawned workers re-import engine.__main__)."""
    args = [sys.executable, "-m", "engine", "render", "--resolution", "48", "32", "--samples", "8", "--quiet"]
    for name, extra in (("pool", []), ("local", ["--cluster", "local"])):
        subprocess.run(args + ["-o", str(tmp_path / f"{name}.exr"), "--stats-json", str(tmp_path / f"{name}.json")]
                       + extra, cwd=REPO, env=_env(REPO), check=True, timeout=120)
    assert json.loads((tmp_path / "local.json").read_text())["parallelism"].startswith("dask local (")
    import OpenImageIO as oiio
    pool, local = (np.asarray(oiio.ImageBuf(str(tmp_path / f"{n}.exr")).get_pixels(oiio.FLOAT)) for n in ("pool", "local"))
    assert pool.mean() > 0 and np.array_equal(pool, local)


def test_the_dask_pool_follows_the_pool_protocol(cluster):
    """The conformance checks of tests/pools/conformance.py, as for the local pools."""
    from tests.pools.conformance import SCENE_SIZE, SETTINGS as PROTOCOL_SETTINGS
    from tests.pools.conformance import check_cancel_answers_every_unit, check_renders_a_frame
    reference = render(cornell_scene(SCENE_SIZE), RenderSettings(threads=1, **PROTOCOL_SETTINGS), **SILENT).image
    check_renders_a_frame(dask(cluster.address), reference)
    check_cancel_answers_every_unit(dask(cluster.address))
    assert cluster.running() == []


def test_the_stopping_rules_are_refused_on_dask_in_one_line(cluster):
    """A Dask pool takes a frame's units once (takes_rounds is False): a noise target is refused."""
    from engine.core.errors import SceneError
    with pytest.raises(SceneError, match="do not work on dask") as err:
        render(cornell_scene((16, 16)), RenderSettings(samples=16, noise_target=0.5), pool=dask(cluster.address),
               **SILENT)
    assert "\n" not in str(err.value) and cluster.running() == []


class SilentPort(int):
    """The port number, and the connections accepted so far."""
    def __new__(cls, port, held):
        self = super().__new__(cls, port)
        self.held = held
        return self


@pytest.fixture
def silent_port():
    """A port on 127.0.0.1 that accepts TCP connections and never sends a byte (not a Dask scheduler)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(16)
    held = []

    def accept():
        while True:
            try:
                held.append(server.accept()[0])
            except OSError:                          # closed at the end of the test
                return

    threading.Thread(target=accept, daemon=True).start()
    try:
        yield SilentPort(server.getsockname()[1], held)
    finally:
        server.close()
        for conn in held:
            conn.close()


def test_a_port_that_accepts_but_never_speaks_dask_is_one_line(silent_port, monkeypatch):
    """distributed's Client waits for the handshake forever there; the probe gives up after
    HANDSHAKE_SECONDS (0.5 s here) with one line naming the address."""
    import engine.pools.dask_cluster as dask_cluster
    monkeypatch.setattr(dask_cluster, "HANDSHAKE_SECONDS", 0.5, raising=False)
    outcome = []

    def try_connect():
        try:
            outcome.append(dask_cluster.connect(f"tcp://127.0.0.1:{silent_port}", timeout=1))
        except BaseException as exc:              # noqa: BLE001 - the test looks at it
            outcome.append(exc)

    thread = threading.Thread(target=try_connect, daemon=True)
    thread.start()
    thread.join(30)                               # main: still waiting (300 s and more)
    assert outcome, "connect() still waits for a handshake"
    assert isinstance(outcome[0], ClusterError), outcome[0]
    message = str(outcome[0])
    assert f"tcp://127.0.0.1:{silent_port}" in message and "does not answer as a Dask scheduler" in message
    assert "\n" not in message


def test_a_stop_request_ends_the_wait_for_a_handshake(silent_port):
    """Ctrl-C (the command line's StopRequest) or Esc while connecting: ConnectStopped at the next
    poll (0.1 s), long before the handshake timeout of 60 s here."""
    from engine.pools.dask_cluster import ConnectStopped, probe_scheduler
    start = time.monotonic()
    with pytest.raises(ConnectStopped, match=f"127.0.0.1:{silent_port}"):
        make_pool(f"dask:tcp://127.0.0.1:{silent_port}", 1, should_cancel=lambda: time.monotonic() > start + 0.3,
                  **SILENT)
    with pytest.raises(ConnectStopped):
        probe_scheduler(f"tcp://127.0.0.1:{silent_port}", handshake=60,
                        should_cancel=lambda: time.monotonic() > start + 0.6)
    assert time.monotonic() - start < 30          # a margin for a loaded machine; without the poll: 60 s


def test_a_scheduler_passes_the_probe(cluster):
    from engine.pools.dask_cluster import probe_scheduler
    probe_scheduler(cluster.address, handshake=30)


@pytest.mark.slow          # waits out the handshake timeout (5 s)
def test_cli_on_a_silent_port_is_one_line_and_ctrl_c_ends_it(silent_port, tmp_path):
    args = [sys.executable, "-m", "engine", "render", "--resolution", "16", "16", "--quiet",
            "-o", str(tmp_path / "a.exr"), "--cluster", f"tcp://127.0.0.1:{silent_port}"]
    start = time.monotonic()
    proc = subprocess.run(args, cwd=REPO, env=_env(REPO), capture_output=True, text=True, timeout=120)
    assert time.monotonic() - start < 25          # 5 s of handshake; room for imports under load
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "does not answer as a Dask scheduler" in lines[0], proc.stderr
    accepted = len(silent_port.held)
    proc = subprocess.Popen(args, cwd=REPO, env=_env(REPO), stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while len(silent_port.held) == accepted and time.monotonic() < deadline:
            time.sleep(0.02)                       # until it waits for the handshake
        proc.send_signal(signal.SIGINT)
        sent = time.monotonic()
        proc.wait(timeout=60)
        returned = time.monotonic() - sent
    finally:
        proc.kill()
    assert proc.returncode == 130, proc.stderr.read()
    assert returned < 3.5                          # under 0.2 s measured; without the poll: the 5-s handshake
    assert not (tmp_path / "a.exr").exists()
