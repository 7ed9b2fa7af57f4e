"""Render a scene on this machine: the one-call entry point over engine/rendering/session.py.

`render(scene, settings)` prepares a RenderSession and runs its work units on local worker
threads or forked processes (engine/pools/local.py), or on a Dask cluster when `cluster` is given
(engine/pools/dask_cluster.py).  Random numbers depend on (seed, pixel, sample, dimension), never on the
workers, so the image for a given seed is identical whatever runs it.
"""
from __future__ import annotations

from .core.allocator import tune_malloc
from .core.version import ENGINE_NAME
from .rendering.session import RenderResult, RenderSession
from .core.settings import RenderSettings
from .pools.local import choose_parallelism, make_workers


def render(scene, settings: RenderSettings | None = None, on_tile=None, should_cancel=None,
           on_progress=None, log=print, progressive: str = "tiles", cluster: str | None = None) -> RenderResult:
    """Render `scene`; see RenderSession.run for the callbacks.  cluster: a Dask scheduler
    address ("tcp://host:port", or "local" for a LocalCluster on this machine)."""
    settings = settings or RenderSettings()
    tune_malloc()                      # keep the bounce temporaries off mmap (engine/core/allocator.py)
    session = RenderSession(scene, settings, log=log, progressive=progressive)
    threads = settings.resolved_threads()
    width, height = scene.resolution
    if cluster:
        from .pools.dask_cluster import DaskWorkers
        workers = DaskWorkers(session, cluster, log=log)
    else:
        parallelism = choose_parallelism(settings.parallelism, threads) if threads > 1 else "threads"
        workers = make_workers(parallelism, session, threads)
    log(f"{ENGINE_NAME}: {width}x{height}, {settings.samples} spp, {settings.shadow_rays} shadow ray(s), "
        f"estimator {settings.estimator}, max depth {settings.max_depth}, {len(session.units)} work units on "
        f"{workers.describe} ({threads} thread(s) here), accelerator {session.accelerator} "
        f"({session.accelerator_reason})")
    log("effect plan:\n" + session.plan.describe())
    return session.run(workers, on_tile=on_tile, should_cancel=should_cancel, on_progress=on_progress)
