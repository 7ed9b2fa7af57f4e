"""Worker processes (engine/pools/processes.py, make_pool("workers")): real processes of this Python,
the same image as the local pool, a killed worker reported by name with its units rendered
elsewhere, Esc within a second."""
import os
import signal
import sys
import time

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.scene.builtin import cornell_scene
from engine.pools.faults import Dispatch, Worker
from engine.pools.processes import SubprocessPool, WorkerError
from engine.pools.spec import make_pool
from tests.load_tolerance import prompt_limit

QUIET = dict(log=lambda *a: None)


def worker_pids(pool):
    return [w.pid for w in pool.workers]


def test_worker_processes_render_the_image_of_render():
    settings = RenderSettings(samples=8, tile_size=16, seed=5)
    ref = render(cornell_scene((48, 32)), settings, **QUIET)
    pool = make_pool("workers", 2, **QUIET)
    result = render(cornell_scene((48, 32)), RenderSettings(samples=8, tile_size=16, seed=5), pool=pool, **QUIET)
    assert np.array_equal(result.image, ref.image)
    assert result.stats["accelerator"] == ref.stats["accelerator"]
    assert result.stats["units_done"] == result.stats["units"] and not result.cancelled
    assert "2 worker process" in result.stats["parallelism"]
    assert all(w.proc.poll() is not None for w in pool.workers)          # closed: none left


def test_a_killed_worker_is_reported_by_name_and_its_units_render_elsewhere():
    settings = RenderSettings(samples=32, tile_size=16, seed=2)
    ref = render(cornell_scene((64, 64)), settings, **QUIET)
    pool = make_pool(f"workers:{sys.executable}", 2, **QUIET)
    victim = pool.workers[0]
    tiles = []

    def on_tile(*args):
        tiles.append(args[:4])
        if len(tiles) == 1:
            os.kill(victim.proc.pid, signal.SIGKILL)

    result = render(cornell_scene((64, 64)), RenderSettings(samples=32, tile_size=16, seed=2), pool=pool,
                    on_tile=on_tile, **QUIET)
    assert np.array_equal(result.image, ref.image)
    expected = f"render worker 1 (pid {victim.proc.pid}) died: killed by SIGKILL"
    assert [r for r in result.stats["worker_reports"] if r.startswith(expected)], result.stats["worker_reports"]
    assert any(expected in w for w in result.warnings)


def test_cancel_returns_within_a_second_and_keeps_finished_units():
    tiles, state = [], {"start": time.perf_counter()}

    def should_cancel():
        if tiles and "at" not in state:
            state["at"] = time.perf_counter()
        return "at" in state

    result = render(cornell_scene((128, 128)), RenderSettings(samples=256, tile_size=32, threads=2),
                    pool=make_pool("workers", 2, **QUIET), on_tile=lambda *a: tiles.append(a[:4]),
                    should_cancel=should_cancel, **QUIET)
    stop = time.perf_counter() - state["at"]
    assert result.cancelled and stop < prompt_limit(state["at"] - state["start"]), (stop, state)
    assert 0 < result.stats["units_done"] < result.stats["units"]


def test_a_python_without_numpy_is_one_message_naming_what_to_install(tmp_path):
    fake = tmp_path / "python"
    fake.write_text("#!/bin/sh\necho \"ModuleNotFoundError: No module named 'numpy'\" >&2\nexit 1\n")
    fake.chmod(0o755)
    with pytest.raises(WorkerError) as err:
        render(cornell_scene((8, 8)), RenderSettings(samples=1, threads=1), pool=make_pool(f"workers:{fake}", 1, **QUIET),
               **QUIET)
    message = str(err.value)
    assert "has no numpy" in message and "pip install numpy embreex" in message and "\n" not in message


def test_an_error_in_a_unit_names_the_worker(monkeypatch):
    scene = cornell_scene((16, 16))
    pool = SubprocessPool(sys.executable, 1, **QUIET)
    pool.prepare(scene, RenderSettings(samples=1, threads=1))
    pool.workers[0].send(("unit", "not a unit"))
    pool.workers[0].in_flight.append("not a unit")
    deadline = time.time() + 20
    item = None
    while item is None and time.time() < deadline:
        item = pool.next_result(0.1)
    pool.close()
    assert item is not None and isinstance(item[2], WorkerError)
    assert str(item[2]).startswith(f"render worker 1 (pid {pool.workers[0].pid}) failed")


class _QueueOnlyWorker(Worker):
    """A worker for the dispatch tests (engine/pools/faults.py): it only records the units it is sent."""

    def send_unit(self, unit):
        pass


def _dispatch_pool(workers: int):
    return Dispatch([_QueueOnlyWorker() for _ in range(workers)], log=lambda *a: None)   # no processes


def test_a_round_of_few_units_gives_every_worker_one_before_any_gets_a_second():
    # An adaptive round at 96x96 is 4 units (one per tile) on 2 workers; with two queued per worker
    # the first worker held the two biggest and the round lasted 1.36x the greedy schedule.
    pool = _dispatch_pool(2)
    pool.start(["t0", "t1", "t2", "t3"])
    assert [w.in_flight for w in pool.workers] == [["t0"], ["t1"]]
    second = pool.workers[1]
    second.in_flight.remove("t1")                  # the worker that finishes first takes the next
    pool.feed(second)
    assert second.in_flight == ["t2"] and list(pool.pending) == ["t3"]


def test_a_round_of_many_units_keeps_a_second_unit_queued_per_worker():
    pool = _dispatch_pool(2)
    pool.start([f"t{i}" for i in range(8)])
    assert [len(w.in_flight) for w in pool.workers] == [2, 2]
    assert sorted(pool.workers[0].in_flight + pool.workers[1].in_flight) == ["t0", "t1", "t2", "t3"]
