"""A pool from its spec: the one way a command line, the add-on or a test picks what renders.

    threads              this process's threads (engine/pools/local.py ThreadPool)
    processes            forked copies of this process (Linux, never inside Blender: ForkPool)
    auto                 processes where they can fork and there is more than one worker, else threads
    workers[:PYTHON]     worker processes of PYTHON (default: this one; engine/pools/processes.py)
    viewport[:PYTHON]    worker processes of PYTHON kept across renders; a new camera prepares nothing
                         again (the 3D viewport: engine/pools/viewport.py)
    dask:ADDRESS         a Dask cluster: tcp://HOST:PORT of its scheduler, or "local" for a
                         LocalCluster started here (engine/pools/dask_cluster.py)

`workers` is how many threads, processes or local Dask workers; a spec that is none of these is a
PoolSpecError, one line naming the kinds.
"""
from __future__ import annotations

import sys

from ..core.errors import SceneError

KINDS = "threads, processes, auto, workers[:PYTHON], viewport[:PYTHON], dask:ADDRESS (tcp://HOST:PORT or local)"


class PoolSpecError(SceneError):
    """Not a pool spec (a SceneError: both command lines print it as one line)."""


def make_pool(spec: str, workers: int = 1, log=print, extra_paths=(), should_cancel=None):
    """The pool (engine/pools/protocol.py) that `spec` names, with `workers` workers; started,
    not yet prepared.  extra_paths: more PYTHONPATH entries for worker processes (bundled wheels).
    should_cancel: polled while a Dask pool connects (Ctrl-C, Esc: engine/pools/dask_cluster.py
    ConnectStopped within 0.1 s)."""
    kind, _, arg = str(spec).strip().partition(":")
    if kind == "auto" and not arg:
        from .local import choose_parallelism
        kind = choose_parallelism("auto", workers)
    if kind == "threads" and not arg:
        from .local import ThreadPool
        return ThreadPool(workers, log=log)
    if kind == "processes" and not arg:
        from .local import ForkPool
        return ForkPool(workers, log=log)
    if kind == "workers":
        from .processes import SubprocessPool
        return SubprocessPool(arg or sys.executable, workers, extra_paths, log=log)
    if kind == "viewport":
        from .viewport import ViewportPool
        return ViewportPool(arg or sys.executable, workers, extra_paths, log=log)
    if kind == "dask" and arg:
        from .dask_cluster import DaskPool, scheduler_address
        return DaskPool(arg if arg == "local" else scheduler_address(arg), workers, log=log,
                        should_cancel=should_cancel)
    raise PoolSpecError(f"not a pool: {spec!r} (expected {KINDS})")

