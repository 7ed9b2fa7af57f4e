"""Viewport workers started ahead (mcrt_addon/warm.py): wanted only for a 3D view of a TNCG15 MC
scene, handed over only when they are the workers the caller would start, stopped when not wanted
or dead; real ones idle without CPU and render what a new pool renders."""
import os
import sys
import time
from types import SimpleNamespace

import numpy as np
import pytest

from engine.core.settings import RenderSettings
from engine.pools.viewport import ViewportPool, ViewportRender
from engine.scene.builtin import cornell_scene


@pytest.fixture
def warm(addon):
    from mcrt_addon import warm
    warm.stop()
    yield warm
    warm.stop()


def window(engine="TNCG15_MC", areas=("VIEW_3D",), threads=0, shading="SOLID"):
    scene = SimpleNamespace(render=SimpleNamespace(engine=engine), tncg15=SimpleNamespace(threads=threads))
    space = SimpleNamespace(shading=SimpleNamespace(type=shading))
    return SimpleNamespace(scene=scene, screen=SimpleNamespace(
        areas=[SimpleNamespace(type=a, spaces=SimpleNamespace(active=space)) for a in areas]))


def test_warm_workers_are_wanted_for_a_3d_view_of_a_tncg15_scene_only(warm):
    key = warm.wanted_key([window(threads=3)])
    assert key is not None and key[0] == sys.executable and key[1] == 3
    assert warm.wanted_key([window()])[1] == (os.cpu_count() or 1)      # Threads 0: one a core, as the viewport
    assert warm.wanted_key([window(engine="CYCLES")]) is None
    assert warm.wanted_key([window(areas=("PROPERTIES", "OUTLINER"))]) is None
    assert warm.wanted_key([]) is None
    assert warm.wanted_key([window()], ahead=False) is None                # the preference turned off
    assert warm.wanted_key([window(engine="CYCLES"), window(areas=("VIEW_3D", "IMAGE_EDITOR"))]) is not None
    assert not warm.busy_elsewhere([window()])
    assert warm.busy_elsewhere([window(), window(shading="RENDERED")])     # a viewport renders: no start now


class FakeWorker:
    def __init__(self):
        self.code = None
        self.proc = SimpleNamespace(poll=lambda: self.code)


class FakePool:
    python = "python"

    def __init__(self, *args, **kwargs):
        self.workers, self.closed, self.warm_sent = [FakeWorker(), FakeWorker()], False, False

    def outstanding(self):
        return 0

    def stats(self):
        return {}

    def warm(self):
        self.warm_sent = True

    def close(self, wait=True):
        self.closed, self.waited = True, wait


def settle(warm):
    deadline = time.monotonic() + 10
    while warm._state["busy"] and time.monotonic() < deadline:
        time.sleep(0.005)


def test_one_warm_pool_is_started_handed_over_only_when_it_fits_and_stopped(warm, monkeypatch):
    monkeypatch.setattr(warm.bridge, "module", lambda name: SimpleNamespace(ViewportPool=FakePool))
    key, other = ("python", 2, ()), ("python", 3, ())
    warm.update(key, start=False)                       # something else runs: nothing is started
    settle(warm)
    assert warm.pool() is None
    warm.update(key, start=True)
    settle(warm)
    pool = warm.pool()
    assert isinstance(pool, FakePool) and pool.warm_sent
    warm.update(key, start=True)                        # kept, not started again
    settle(warm)
    assert warm.pool() is pool
    assert warm.take(*other) is None and warm.pool() is pool        # other workers: not handed over
    assert warm.take(*key) is pool and warm.pool() is None          # the caller's now
    assert warm.take(*key) is None
    warm.update(key, start=True)
    settle(warm)
    second = warm.pool()
    warm.update(None, start=False)                      # the engine changed: stopped (on a thread)
    deadline = time.monotonic() + 5
    while not second.closed and time.monotonic() < deadline:
        time.sleep(0.005)
    assert second.closed and warm.pool() is None
    warm.update(key, start=True)
    settle(warm)
    third = warm.pool()
    third.workers[1].code = -9                          # a worker died: neither handed over nor kept
    assert warm.take(*key) is None
    warm.update(key, start=False)
    assert warm.pool() is None
    deadline = time.monotonic() + 5
    while not third.closed and time.monotonic() < deadline:
        time.sleep(0.005)
    assert third.closed


def test_workers_that_fail_to_start_or_die_are_not_started_again_and_again(warm, monkeypatch):
    made = []

    class Failing(FakePool):
        def __init__(self, *args, **kwargs):
            made.append(self)
            raise OSError("no such Python")

    monkeypatch.setattr(warm.bridge, "module", lambda name: SimpleNamespace(ViewportPool=Failing))
    warm._state["failures"].clear()
    key = ("python", 2, ())
    for _ in range(5):
        warm.update(key, start=True)
        settle(warm)
    assert len(made) == warm.MAX_FAILURES and warm.pool() is None     # not one start a second forever
    monkeypatch.setattr(warm.bridge, "module", lambda name: SimpleNamespace(ViewportPool=FakePool))
    other = ("python", 3, ())                           # another key (the Threads setting changed): tried
    warm.update(other, start=True)
    settle(warm)
    pool = warm.pool()
    assert isinstance(pool, FakePool)
    for _ in range(warm.MAX_FAILURES):                  # its workers die, each new pool too
        warm.pool().workers[0].code = -11
        warm.update(other, start=True)                  # stops the dead one
        warm.update(other, start=True)                  # starts another while under the limit
        settle(warm)
    assert warm.pool() is None
    warm.update(other, start=True)
    settle(warm)
    assert warm.pool() is None                          # control: below the limit a start happened above
    warm._state["failures"].clear()


def test_no_kernels_are_loaded_ahead_for_a_scene_on_the_numpy_backend(warm, monkeypatch):
    monkeypatch.setattr(warm.bridge, "module", lambda name: SimpleNamespace(ViewportPool=FakePool))
    win = window()
    win.scene.tncg15.backend = "numpy"
    assert not warm.numba_wanted([win])
    warm.update(("python", 2, ()), start=True, load_kernels=warm.numba_wanted([win]))
    settle(warm)
    assert warm.pool() is not None and not warm.pool().warm_sent
    win.scene.tncg15.backend = "auto"                   # control: the default loads them
    assert warm.numba_wanted([win])


def test_no_warm_pool_beside_the_workers_persistent_data_keeps(warm):
    key = ("python", 2, ())
    usable = {"now": True}
    warm.hold(key, lambda: usable["now"])
    try:
        assert warm.kept_elsewhere(key) and not warm.kept_elsewhere(("python", 3, ()))
        usable["now"] = False                           # the kept pool lost a worker: a warm one may start
        assert not warm.kept_elsewhere(key)
    finally:
        warm.hold(None, None)
    assert not warm.kept_elsewhere(key)


def worker_cpu(pids):
    ticks = 0
    for p in pids:
        fields = open(f"/proc/{p}/stat").read().rsplit(")", 1)[1].split()
        ticks += int(fields[11]) + int(fields[12])
    return ticks / os.sysconf("SC_CLK_TCK")


def first_and_converged(render, scene, settings):
    t0 = time.perf_counter()
    render.set_scene(scene, settings, 4, start_resolution=8)
    first = None
    deadline = t0 + 120
    while not render.converged():
        assert time.perf_counter() < deadline and render.error is None, render.error
        if first is None and render.picture().rgba is not None:
            first = time.perf_counter() - t0
        time.sleep(0.005)
    return first, render.picture().rgba.copy()


@pytest.mark.slow           # two pools of real workers (about 5-10 s)
def test_a_warm_pool_idles_without_cpu_is_taken_by_the_viewport_and_renders_the_same(warm):
    key = warm.pool_key(sys.executable, 2, ())
    warm.update(key, start=True)
    settle(warm)
    pool = warm.pool()
    assert isinstance(pool, ViewportPool)
    pids = [w.pid for w in pool.workers]
    deadline = time.monotonic() + 120
    while not pool.warmed():                            # imports and numba's loads done
        assert time.monotonic() < deadline, "the workers started ahead never finished loading"
        time.sleep(0.05)
    before = worker_cpu(pids)
    time.sleep(1.0)
    assert worker_cpu(pids) - before < 0.02, "idle warm workers must not use CPU"
    scene, settings = cornell_scene((40, 30)), RenderSettings(max_depth=3, seed=5)
    made = []

    def make_pool():                                    # as mcrt_addon/viewport.py ViewportState
        made.append(True)
        return ViewportPool(sys.executable, 2, log=lambda *a: None)
    taken = ViewportRender(make_pool=lambda: warm.take(*key) or make_pool())
    cold = ViewportRender(make_pool=make_pool)
    try:
        first_warm, image_warm = first_and_converged(taken, scene, settings)
        assert taken.pids == pids and warm.pool() is None and not made
        first_cold, image_cold = first_and_converged(cold, scene, settings)
        assert made
        print(f"first picture: warm pool {first_warm:.3f} s, new pool {first_cold:.3f} s "
              f"(load {os.getloadavg()[0]:.1f})")
        assert np.array_equal(image_warm, image_cold)
    finally:
        taken.close()
        cold.close()


def test_a_final_render_uses_the_warm_pool_for_one_render_only(warm, monkeypatch):
    from engine.pools.kept import KeptPool
    modules = {"pools.viewport": SimpleNamespace(ViewportPool=FakePool),
               "pools.kept": SimpleNamespace(KeptPool=KeptPool)}
    monkeypatch.setattr(warm.bridge, "module", lambda name: modules.get(name, SimpleNamespace()))
    key = ("python", 2, ())
    assert warm.render_pool("python", 2, ()) is None                # none started: the render starts its own
    warm.update(key, start=True)
    settle(warm)
    inner = warm.pool()
    pool = warm.render_pool("python", 2, (), log=print)
    assert pool.inner is inner and warm.pool() is None and inner.log is print
    assert pool.stats()["persistent_data"] is False
    pool.close()                                                    # the render is over: so are its workers
    assert inner.closed and inner.waited is False                   # ... without waiting for their ends
    kept = KeptPool(FakePool(), checked=True)                       # control: Persistent Data's pool stays
    kept.close()
    assert not kept.inner.closed and kept.stats()["persistent_data"] is True
