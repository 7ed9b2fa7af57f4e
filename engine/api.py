"""Render a scene: the one entry point, `render(scene, settings, pool)`.

The frame side (tiles, units, the ordered merge, the film, the result: engine/rendering/frame.py)
runs here; the pool (engine/pools/protocol.py, made by engine/pools/spec.py make_pool) has its
workers build the tracer side (engine/rendering/session.py PreparedScene) and trace the units:
this process's threads, forked processes, worker processes of another Python, a Dask cluster.
Random numbers depend on (seed, pixel, sample, dimension), never on the workers, so the image for
a given seed is identical whatever pool renders it.
"""
from __future__ import annotations

from .core.allocator import tune_malloc
from .core.settings import RenderSettings
from .core.version import ENGINE_NAME
from .pools.spec import make_pool
from .rendering.frame import Frame, RenderResult

__all__ = ["render", "make_pool", "RenderResult"]


def render(scene, settings: RenderSettings | None = None, pool=None, on_tile=None, should_cancel=None,
           on_progress=None, log=print, progressive: str = "tiles") -> RenderResult:
    """Render `scene` on `pool` (default: the local pool of settings.parallelism and threads) and
    close the pool.  Callbacks (engine/rendering/frame.py Frame.run): on_tile(x0, y0, x1, y1, pixels),
    should_cancel(), on_progress(fraction, message); progressive: "tiles" or "frame"."""
    settings = settings or RenderSettings()
    settings.validate()
    tune_malloc()                      # keep the bounce temporaries off mmap (engine/core/allocator.py)
    threads = settings.resolved_threads()
    if pool is None:                   # one thread is always this process's own
        pool = make_pool(settings.parallelism if threads > 1 else "threads", threads, log=log)
    try:
        facts = pool.prepare(scene, settings)
        frame = Frame(scene, settings, facts, progressive)
    except BaseException:
        pool.close()
        raise
    width, height = frame.resolution
    log(f"{ENGINE_NAME}: {width}x{height}, {settings.samples} spp, {settings.shadow_rays} shadow ray(s), "
        f"estimator {settings.estimator}, max depth {settings.max_depth}, {len(frame.units)} work units on "
        f"{pool.describe} ({threads} thread(s) here), accelerator {facts.accelerator} "
        f"({facts.accelerator_reason})")
    log("effect plan:\n" + facts.plan.describe())
    result = frame.run(pool, on_tile=on_tile, should_cancel=should_cancel, on_progress=on_progress)
    for warning in frame.warnings[len(facts.warnings):]:       # found while rendering (the tracer's are logged)
        log(f"warning: {warning}")
    result.stats.update(pool.stats())
    result.warnings = list(result.warnings) + list(pool.warnings())
    return result
