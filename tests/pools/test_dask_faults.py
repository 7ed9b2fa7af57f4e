"""The fault model of engine/pools/faults.py on a Dask cluster (engine/pools/dask_watch.py), with real
`dask scheduler` / `dask worker` processes on 127.0.0.1 and real signals: a SIGSTOPped worker is
removed at its unit deadline and the image is bit-identical; Ctrl-C returns although a worker is
stopped; with no worker left, or with the scheduler killed, the render ends with one line and keeps
its finished units.  Every time limit here is a guard against a hang, not a timing requirement."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from engine import RenderSettings, render                     # noqa: E402
from engine.core.errors import WorkersLost                    # noqa: E402
from engine.film.image_files import read_image                # noqa: E402
from engine.pools import dask_watch, faults                   # noqa: E402
from engine.pools.dask_cluster import ProcessCluster          # noqa: E402
from engine.pools.spec import make_pool                       # noqa: E402
from engine.scene.builtin import cornell_scene                # noqa: E402
from tests.load_tolerance import guarded                       # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
HANG = 150.0       # seconds: a guard against a hang (main waited for worker-ttl, 300 s), not a timing check
QUIET = dict(log=lambda *a: None)
SIZE = (96, 96)


def settings():
    return RenderSettings(samples=48, tile_size=16, seed=7)




@pytest.fixture
def cluster(tmp_path):
    c = ProcessCluster(tmp_path / "dask", workers=2)
    try:
        yield c
    finally:
        c.close()


@pytest.fixture(scope="module")
def reference():
    return render(cornell_scene(SIZE), settings(), pool=make_pool("threads", 2, **QUIET), **QUIET).image


def worker_pids(cluster):
    """{worker address: pid of the worker process} (under its nanny)."""
    return cluster.client.run(os.getpid)


def render_on(cluster, action, should_cancel=None):
    """Render on the cluster; action(pool) runs once, when the first tile is merged."""
    pool = make_pool(f"dask:{cluster.address}", 2, **QUIET)
    tiles = []

    def on_tile(*args):
        tiles.append(args[:4])
        if len(tiles) == 1:
            action(pool)

    return guarded(HANG, lambda: render(cornell_scene(SIZE), settings(), pool=pool, on_tile=on_tile,
                                  should_cancel=should_cancel, **QUIET))


# -- the clock, without a cluster --------------------------------------------------------------------
def test_the_unit_clock_finds_a_worker_that_finishes_nothing(monkeypatch):
    monkeypatch.setattr(faults, "DEADLINE_MIN", 5.0)
    clock = dask_watch.UnitClock(first_extra=2.0)
    assert clock.observe({"a": ["u1", "u2"], "b": ["u3"]}, 0.0) == []
    assert clock.observe({"a": ["u2", "u4"], "b": ["u3"]}, 1.0) == []       # a finished its first unit
    assert clock.observe({"a": ["u4", "u5"], "b": ["u3"]}, 2.0) == []       # and a second: 1 s measured
    assert clock.slowest == 1.0
    assert clock.limit("a") == 10.0 and clock.limit("b") == 12.0           # 10 x 1 s; b's first + 2 s
    for t in range(3, 12):                                                  # a finishes one a second
        assert clock.observe({"a": [f"v{t}"], "b": ["u3"]}, float(t)) == []
    assert clock.observe({"a": ["v11"], "b": ["u3"]}, 12.5) == [("b", 12.0)]
    assert clock.observe({"a": [], "b": ["u3"]}, 30.0) == []               # reported once


def test_a_worker_gone_from_the_scheduler_is_no_longer_watched(monkeypatch):
    monkeypatch.setattr(faults, "DEADLINE_MIN", 5.0)
    clock = dask_watch.UnitClock()
    clock.observe({"a": ["u1"]}, 0.0)
    assert clock.observe({}, 100.0) == [] and clock.held == {}


class FetchNeverAnswers:
    """A finished unit whose holder does not answer (a SIGSTOPped worker): every fetch times out."""
    def __init__(self, pool, cancel_after=None, answer_after=None):
        self.pool, self.cancel_after, self.answer_after, self.calls = pool, cancel_after, answer_after, 0

    def result(self, timeout=None):
        assert timeout is not None, "a fetch without a timeout waits for a stopped worker until worker-ttl"
        self.calls += 1
        if self.calls == self.cancel_after:
            self.pool.cancelled = True
        if self.calls == self.answer_after:
            return "the unit's result"
        raise TimeoutError


def test_a_cancel_drops_a_finished_unit_whose_worker_does_not_answer():
    from engine.pools.dask_cluster import DaskPool
    pool = object.__new__(DaskPool)            # the results thread's fetch alone, no cluster
    pool.cancelled = pool.fetch_stalled = False
    fetch = FetchNeverAnswers(pool, cancel_after=3)
    assert pool._result(fetch) is None and fetch.calls == 3       # dropped at the first step after the cancel
    later = FetchNeverAnswers(pool)
    assert pool._result(later) is None and later.calls == 0       # the next ones: dropped without a fetch
    pool.cancelled = pool.fetch_stalled = False
    fetch = FetchNeverAnswers(pool, answer_after=5)                # not cancelled: it waits for the answer
    assert pool._result(fetch) == "the unit's result" and fetch.calls == 5


class LostThenComputedAgain:
    """A finished unit whose result went with a removed worker (status "lost") and which the scheduler
    computes again: as_completed yields it once lost, and again once finished when added back."""
    def __init__(self):
        self.key, self.status = "tncg15-unit-0", "lost"

    def result(self, timeout=None):
        assert self.status == "finished"
        return "the unit's result"

    def exception(self, timeout=None):
        return None


class FakeCompleted:
    """distributed.as_completed over fakes: add() puts a future back, finished (the scheduler's second run)."""
    def __init__(self, futures, loop=None):
        self.queue = list(futures)

    def __iter__(self):
        while self.queue:
            yield self.queue.pop(0)

    def add(self, future):
        future.status = "finished"
        self.queue.append(future)


def results_of(cancelled, monkeypatch):
    import queue
    import threading
    from types import SimpleNamespace
    from engine.pools.dask_cluster import DaskPool
    monkeypatch.setattr(distributed, "as_completed", FakeCompleted)
    pool = object.__new__(DaskPool)            # the results thread alone, no cluster
    future = LostThenComputedAgain()
    pool.cancelled, pool.fetch_stalled, pool.futures = cancelled, False, [future]
    pool.unit_of, pool.answered, pool.answer_lock, pool.finished = {future.key: "unit"}, set(), threading.Lock(), queue.Queue()
    pool.client, pool.address = SimpleNamespace(loop=None), "tcp://127.0.0.1:1"
    pool._collect_results()
    return pool.finished.get_nowait()


def test_a_result_lost_with_a_removed_worker_is_awaited_again(monkeypatch):
    assert results_of(False, monkeypatch) == ("unit", "the unit's result", None)
    unit, result, error = results_of(True, monkeypatch)     # control: cancelled, the lost unit is not awaited
    assert result is None and "lost" in str(error)


# -- a cluster of real processes -------------------------------------------------------------------
@pytest.mark.slow          # a cluster of processes and a 5 s deadline (today's main: hung for worker-ttl, 300 s)
def test_a_stopped_dask_worker_is_removed_at_its_unit_deadline_and_the_image_is_bit_identical(
        cluster, reference, monkeypatch):
    monkeypatch.setattr(faults, "DEADLINE_MIN", 5.0)
    victim = {}

    def stop(pool):
        victim["address"], victim["pid"] = sorted(worker_pids(cluster).items())[0]
        os.kill(victim["pid"], signal.SIGSTOP)

    result = render_on(cluster, stop)
    assert np.array_equal(result.image, reference)
    assert not result.cancelled and result.stats["units_done"] == result.stats["units"]
    assert any(f"Dask worker {victim['address']} stopped answering" in w for w in result.warnings), result.warnings


@pytest.mark.slow          # a cluster of processes
def test_a_cancel_returns_although_a_dask_worker_is_stopped(cluster):
    state = {}

    def stop(pool):
        os.kill(sorted(worker_pids(cluster).values())[0], signal.SIGSTOP)
        state["at"] = time.perf_counter()

    result = render_on(cluster, stop, should_cancel=lambda: "at" in state)
    waited = time.perf_counter() - state["at"]
    print(f"a cancel with a stopped Dask worker returned after {waited:.2f} s")
    assert result.cancelled and 0 < result.stats["units_done"] < result.stats["units"]
    assert waited < faults.DEADLINE_MIN, waited    # a hang guard: the cancel did not wait for the deadline


@pytest.mark.slow          # a cluster of processes and the 10 s "no worker left" grace
def test_with_no_dask_worker_left_the_render_is_one_line_and_keeps_its_finished_units(cluster):
    def kill_all(pool):
        for proc in cluster.procs[1:]:           # each worker with its nanny: nothing restarts them
            cluster.stop(proc)

    with pytest.raises(WorkersLost) as err:
        render_on(cluster, kill_all)
    assert "no Dask worker is left" in str(err.value) and "\n" not in str(err.value), err.value
    kept = err.value.result
    assert kept is not None and kept.cancelled and 0 < kept.stats["units_done"] < kept.stats["units"]
    assert kept.image.shape == (SIZE[1], SIZE[0], 3) and kept.image.max() > 0


@pytest.mark.slow          # a cluster of processes (today's main: a ClusterError, nothing kept)
def test_a_killed_scheduler_ends_the_render_in_one_line_and_keeps_its_finished_units(cluster):
    with pytest.raises(WorkersLost) as err:
        render_on(cluster, lambda pool: cluster.stop(cluster.procs[0]))
    assert "\n" not in str(err.value) and cluster_address_in(str(err.value), cluster), err.value
    kept = err.value.result
    assert kept is not None and 0 < kept.stats["units_done"] < kept.stats["units"]
    assert kept.image.max() > 0


def units_finished(dask_scheduler):
    """On the scheduler: how many units of a render are finished (their results held)."""
    return sum(1 for key, ts in dask_scheduler.tasks.items()
               if str(key).startswith("tncg15-unit-") and ts.state == "memory")


units_finished.__module__ = "__main__"       # pickled by value: the scheduler has no copy of the tests


def cluster_address_in(text, cluster):
    return cluster.address in text


@pytest.mark.slow          # the command lines against a cluster of processes
@pytest.mark.parametrize("cli", ["engine", "mcrt_addon"])
def test_the_cli_writes_the_finished_tiles_when_the_scheduler_is_killed(cli, cluster, tmp_path):
    out = tmp_path / "part.exr"
    scene = ["--builtin", "cornell"] if cli == "engine" else [os.path.join(ROOT, "sample_blends", "cornell.blend")]
    proc = subprocess.Popen([sys.executable, "-m", cli, "render", *scene, "--resolution", "128", "128",
                             "--samples", "256", "--cluster", cluster.address, "-o", str(out)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + HANG
    while cluster.client.run_on_scheduler(units_finished) < 4:   # mid-render: some units finished
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.05)
    cluster.stop(cluster.procs[0])
    try:
        _, err = proc.communicate(timeout=HANG)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("the command line hung after its scheduler was killed")
    assert proc.returncode == 1, err
    lines = [line for line in err.splitlines() if "error:" in line]
    assert len(lines) == 1 and "finished tiles" in lines[0], err
    assert read_image(str(out)).max() > 0
