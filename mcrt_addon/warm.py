"""Viewport workers started ahead: Rendered mode's first picture without a worker start.

Entering Rendered mode used to start the viewport's worker processes then (a Python start, the
tracer's imports, numba's loads: most of the 1.3 s before the first coarse picture,
docs/performance.md "The Rendered viewport").  While TNCG15 MC is the scene's engine and a window
shows a 3D view, a timer on the UI thread (every TICK_SECONDS; it reads a few properties) keeps one
pool of viewport workers (engine/pools/viewport.py ViewportPool) started and idle: imported, numba's
kernels loaded (ViewportPool.warm), blocked on their pipes, using no CPU.  The viewport
(mcrt_addon/viewport.py) and a final render with Persistent Data (mcrt_addon/persistent.py) `take`
it, and a final render without it uses it for that render (`render_pool`), when it has the workers
they would start (same Python, count and paths); the next one is started after QUIET_TICKS ticks in
which no viewport rendered and no render or material preview ran.  A warm pool renders exactly what
a new one would (the image does not depend on the pool, engine/pools/protocol.py).

The pool is stopped when the scene's engine is no longer TNCG15 MC or no 3D view is left, when a
file is loaded (load_pre), and when the add-on is unregistered; its workers also exit with Blender
(they watch their parent).  Never in background mode (``blender -b``): no window, no viewport.
Processes start and stop on a thread of their own: the UI thread never waits for them; that thread
also imports the modules the first export and frame import in Blender's process (PREIMPORT).
"""
import threading

import bpy

from . import bridge, worker_python

TICK_SECONDS = 1.0
QUIET_TICKS = 2         # a start waits until this many ticks in a row wanted it (a file just opened
                        # often renders its material previews first: the warm start would slow them)
ENGINE = "TNCG15_MC"

# The tracer's modules the viewport's first export and frame import in Blender's process
# (mcrt_addon/viewport.py export, engine/pools/viewport.py ViewportRender._frame; Frame.scheduled
# imports the photon passes, and with them scipy: 0.28 CPU s).
PREIMPORT = ("scene.model", "core.settings", "pools.denoiser", "rendering.frame", "rendering.units",
             "rendering.photon_passes")

MAX_FAILURES = 2        # a key whose workers failed to start or died this often is not started again
                        # (until the key changes: another Python, thread count or paths)

_lock = threading.Lock()
_state = {"pool": None, "key": None, "busy": False,   # busy: a thread is starting or stopping a pool
          "quiet": 0,                                  # ticks in a row that wanted a start
          "failures": {}, "said": False,               # key -> failed starts or deaths; a tick's error told
          "held": None}                                # (key, usable) of the pool Persistent Data keeps
started = []            # keys of the pools started here (tests, diagnostics)


def worker_count(scene) -> int:
    """The viewport's worker count for `scene` (worker_python.viewport_worker_count, the one rule)
    from the Threads property alone: the tracer is not imported on the UI thread for it."""
    return worker_python.viewport_worker_count(int(getattr(getattr(scene, "tncg15", None), "threads", 0) or 0))


def pool_key(python, count, extra_paths):
    return (python, int(count), tuple(extra_paths))


def wanted_key(windows, preferred="", ahead=True):
    """The key of the pool to keep warm for these windows, or None when none is wanted: the
    preference Start Workers Ahead is off, no window shows a 3D view of a scene whose engine is
    TNCG15 MC, or no worker Python is there."""
    scenes = [w.scene for w in windows if w.scene is not None and w.scene.render.engine == ENGINE
              and any(a.type == "VIEW_3D" for a in w.screen.areas)]
    if not scenes or not ahead:
        return None
    python, _ = worker_python.worker_python(preferred)
    if python is None or worker_python.NUMPY_PROBLEM:
        return None
    return pool_key(python, worker_count(scenes[0]), worker_python.extra_paths())


def busy_elsewhere(windows) -> bool:
    """A Rendered viewport, a render or a material preview runs: a warm start now would take CPU from it."""
    if any(a.type == "VIEW_3D" and a.spaces.active.shading.type == "RENDERED"
           for w in windows for a in w.screen.areas):
        return True
    running = getattr(bpy.app, "is_job_running", None)
    return bool(running is not None and (running("RENDER") or running("RENDER_PREVIEW")))


def alive(pool) -> bool:
    return all(w.proc.poll() is None for w in pool.workers)


def take(python, count, extra_paths):
    """The warm pool when it has these workers and all are alive (it is then the caller's), else None."""
    key = pool_key(python, count, extra_paths)
    with _lock:
        pool = _state["pool"]
        if pool is None or _state["key"] != key or not alive(pool):
            return None
        _state["pool"] = _state["key"] = None
        return pool


def render_pool(python, count, extra_paths, log=print):
    """A final render's pool made of the warm workers when they fit (engine/pools/kept.py KeptPool
    for one render: its close() stops them), else None (the render starts its own)."""
    pool = take(python, count, extra_paths)
    if pool is None:
        return None
    pool.log = log
    # checked: render_engine validates every exported scene before rendering it
    return bridge.module("pools.kept").KeptPool(pool, checked=True, keep=False)


def kept_elsewhere(key) -> bool:
    """Persistent Data keeps a pool of these workers (mcrt_addon/persistent.py tells `hold`): a warm
    one beside it would double the idle processes."""
    held = _state["held"]
    return held is not None and held[0] == key and held[1]()


def hold(key, usable) -> None:
    """Persistent Data keeps the workers of `key` while usable() (mcrt_addon/persistent.py), or
    nothing (key None): no warm pool of that key is started beside them."""
    _state["held"] = None if key is None else (key, usable)


def tick():
    """bpy.app.timers, on the UI thread: update() with what Blender's windows want now.  It never
    raises (Blender drops a timer that does)."""
    try:
        wm = bpy.context.window_manager
        key = None if bpy.app.background or wm is None else wanted_key(wm.windows, worker_python.preferred_python(),
                                                                        worker_python.start_ahead())
        if key is not None and kept_elsewhere(key):
            key = None
        start = key is not None and not busy_elsewhere(wm.windows)
        _state["quiet"] = _state["quiet"] + 1 if start else 0
        update(key, start and _state["quiet"] >= QUIET_TICKS, load_kernels=numba_wanted(wm.windows))
    except (AttributeError, ReferenceError, RuntimeError):     # no window yet, a scene being freed
        pass
    except Exception as exc:                # noqa: BLE001 - told once; the timer keeps running
        if not _state["said"]:
            _state["said"] = True
            print(f"TNCG15 MC: workers started ahead: {type(exc).__name__}: {exc}")
    return TICK_SECONDS


def numba_wanted(windows) -> bool:
    """Whether the workers started ahead may load numba's kernels (and start their compile on a cold
    cache): not when the scene's Backend is NumPy."""
    scenes = [w.scene for w in windows if w.scene is not None and w.scene.render.engine == ENGINE]
    return not scenes or getattr(getattr(scenes[0], "tncg15", None), "backend", "auto") != "numpy"


def update(key, start: bool, load_kernels: bool = True) -> None:
    """Stop the warm pool unless it is the one of `key` with every worker alive; start that one
    (on a thread) when there is none and `start` (nothing else runs), unless its workers failed
    MAX_FAILURES times (a start that raised, a worker that died)."""
    with _lock:
        pool = _state["pool"]
        if _state["busy"]:
            return
        failures = _state["failures"]
        if pool is not None and (_state["key"] != key or not alive(pool)):
            if _state["key"] == key:        # a worker died
                failures[key] = failures.get(key, 0) + 1
            _stop_locked()                  # the engine or settings changed, or a worker died
        elif pool is None and start and key is not None and failures.get(key, 0) < MAX_FAILURES:
            _state["busy"], _state["key"], _state["quiet"] = True, key, 0
            threading.Thread(target=_start, args=(key, load_kernels), daemon=True,
                             name="viewport warm start").start()


def _start(key, load_kernels=True):
    python, count, extra = key
    pool = None
    try:
        pool = bridge.module("pools.viewport").ViewportPool(python, count, extra, log=lambda *a: None)
        if load_kernels:
            pool.warm()                     # numba's kernels loaded while nobody waits
    except Exception:                       # noqa: BLE001 - the viewport reports a failed start itself
        pool = None
    try:
        for name in PREIMPORT:              # what entering Rendered imports here (0.5 CPU s) imported now
            bridge.module(name)
        from . import export  # noqa: F401
    except Exception:                       # noqa: BLE001 - the viewport's first frame says why
        pass
    with _lock:
        _state["busy"] = False
        if pool is None:
            _state["failures"][key] = _state["failures"].get(key, 0) + 1
        if pool is not None and _state["key"] == key:
            _state["pool"] = pool
            started.append(key)
            return
    if pool is not None:
        pool.close()                        # stopped (stop()) while it started


def _stop_locked():
    pool, _state["pool"], _state["key"] = _state["pool"], None, None
    if pool is not None:
        threading.Thread(target=pool.close, daemon=True, name="viewport warm stop").start()


@bpy.app.handlers.persistent
def stop(*_args):
    """Stop the warm pool (also a load_pre handler)."""
    with _lock:
        _stop_locked()


def pool():
    """The warm pool, or None (tests, diagnostics)."""
    return _state["pool"]


def register():
    if stop not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(stop)
    if not bpy.app.background and not bpy.app.timers.is_registered(tick):
        bpy.app.timers.register(tick, first_interval=TICK_SECONDS, persistent=True)


def unregister():
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)
    if stop in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(stop)
    stop()
