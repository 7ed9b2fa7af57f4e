"""The viewport's pool (engine/pools/viewport.py) under the fault model of engine/pools/faults.py,
with real signals: a worker killed (SIGKILL) or stopped (SIGSTOP) mid-frame is named, started
again with the scene of the moment, and the frame is bit-identical; a new view after a cancel does
not wait for a stopped worker.  Every time limit here is a guard against a hang, not a timing check."""
import os
import signal
import time
from dataclasses import replace

import numpy as np
import pytest

from engine.api import render
from engine.core.settings import RenderSettings
from engine.pools import faults
from engine.pools.spec import make_pool
from engine.rendering.frame import Frame
from engine.scene.builtin import cornell_scene
from tests.file_safety import alive
from tests.pools.conformance import drain

SETTINGS = RenderSettings(max_depth=3, seed=5, samples=64, tile_size=16, accelerator="embree")
SCENE = cornell_scene((96, 64))
HANG = 60.0


@pytest.fixture
def pool():
    p = make_pool("viewport", 2, log=lambda *a: None)
    yield p
    pids = [w.pid for w in p.workers]
    p.close()
    assert not any(alive(pid) for pid in pids)


@pytest.fixture(scope="module")
def reference():
    return render(SCENE, replace(SETTINGS, threads=1), log=lambda *a: None).image


def busy(pool):
    """A worker holding units."""
    return next(w for w in pool.workers if w.in_flight)


def frame_with(pool, action, scene=SCENE):
    """One frame on `pool`; action(pool) once, after the first unit merged.  Returns the frame."""
    facts = pool.prepare(scene, SETTINGS)
    frame = Frame(scene, SETTINGS, facts)
    pool.start(frame.units)
    first = drain(pool, 1, timeout=HANG)
    action(pool)
    for unit, result, error in first + drain(pool, len(frame.units) - 1, timeout=HANG):
        assert error is None and result is not None, error
        frame.add(result)
    return frame


@pytest.mark.slow          # two frames and a restarted worker (about 5 s)
def test_a_killed_viewport_worker_is_named_and_restarted_and_the_frame_is_bit_identical(pool, reference):
    victim = {}

    def kill(pool):
        victim["pid"] = busy(pool).pid
        os.kill(victim["pid"], signal.SIGKILL)

    frame = frame_with(pool, kill)
    assert np.array_equal(frame.film.mean(), reference)
    report = pool.stats()["worker_reports"][0]
    assert f"pid {victim['pid']}) died: killed by SIGKILL; restarted as viewport worker " in report, report
    assert pool.notice() == report                              # the viewport's header shows it
    assert victim["pid"] not in [w.pid for w in pool.workers] and all(alive(w.pid) for w in pool.workers)
    again = frame_with(pool, lambda p: None)                    # the restarted worker renders too
    assert np.array_equal(again.film.mean(), reference)


@pytest.mark.slow          # waits out a 3 s unit deadline
def test_a_stopped_viewport_worker_is_killed_at_its_unit_deadline_and_restarted(pool, reference, monkeypatch):
    monkeypatch.setattr(faults, "DEADLINE_MIN", 3.0)
    victim = {}

    def stop(pool):
        victim["pid"] = busy(pool).pid
        os.kill(victim["pid"], signal.SIGSTOP)

    frame = frame_with(pool, stop)
    assert np.array_equal(frame.film.mean(), reference)
    report = pool.stats()["worker_reports"][0]
    assert f"pid {victim['pid']}) died: stopped answering" in report and "restarted as" in report, report


@pytest.mark.slow          # two frames, a stopped worker killed after the cancel
def test_a_new_view_after_a_cancel_does_not_wait_for_a_stopped_viewport_worker(pool):
    facts = pool.prepare(SCENE, SETTINGS)
    frame = Frame(SCENE, SETTINGS, facts)
    pool.start(frame.units)
    drain(pool, 1, timeout=HANG)
    stopped = busy(pool).pid
    os.kill(stopped, signal.SIGSTOP)
    t0 = time.perf_counter()
    pool.cancel()
    drain(pool, len(frame.units) - 1, timeout=HANG)             # today's main: waited forever
    assert time.perf_counter() - t0 < faults.DEADLINE_MIN       # a hang guard: not the unit deadline
    view = replace(SCENE, camera=replace(SCENE.camera, lens=SCENE.camera.lens * 1.5))
    frame = frame_with(pool, lambda p: None, scene=view)
    expected = render(view, replace(SETTINGS, threads=1), log=lambda *a: None).image
    assert np.array_equal(frame.film.mean(), expected)
    assert any(f"pid {stopped}) died: did not stop" in r for r in pool.stats()["worker_reports"])


@pytest.mark.slow          # starts a worker twice and loads the kernels twice (about 5 s)
def test_a_worker_restarted_before_any_scene_is_warmed_too():
    """A warm pool (mcrt_addon/warm.py) whose worker died before its first scene: the replacement is
    asked to load the kernels as well, else warmed() waits for it for ever (bench-materials' 300 s)."""
    p = make_pool("viewport", 1, log=lambda *a: None)
    try:
        p.warm()
        deadline = time.monotonic() + HANG
        while not p.warmed():
            assert time.monotonic() < deadline, "the worker never answered warm"
            time.sleep(0.02)
        first = p.workers[0]
        os.kill(first.pid, signal.SIGKILL)
        while not p.warmed() or p.workers[0] is first:        # warmed() reads the pool's events
            assert time.monotonic() < deadline + HANG, (p.reports, [w.warmed for w in p.workers])
            time.sleep(0.02)
        assert p.restarts == 1 and p.workers[0].warmed and p.workers[0].alive
    finally:
        pids = [w.pid for w in p.workers]
        p.close()
    assert not any(alive(pid) for pid in pids)
