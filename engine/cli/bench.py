"""`python -m engine bench`: throughput figures measured in one run.

Prints rays/s per kind, paths/s, how worker time splits between Embree calls, the
NumPy sphere and quad kernels and the rest, and the speed-up from 1 worker to all
cores, all on the built-in scene and in one run (the machines here are noisy).
"""
from __future__ import annotations

import os
import platform
import tempfile
import time

from ..scene.builtin import cornell_scene
from ..api import render
from ..core.settings import RenderSettings


def _run(resolution, samples, threads, repeats=2):
    """Best of `repeats` renders: the shared machines here are noisy."""
    best = None
    for _ in range(repeats):
        stats = render(cornell_scene(resolution), RenderSettings(samples=samples, threads=threads),
                       log=lambda *a: None).stats
        if best is None or stats["render_seconds"] < best["render_seconds"]:
            best = stats
    return best


def run_bench(resolution=(256, 256), samples=64) -> dict:
    cores = os.cpu_count() or 1
    print(f"TNCG15 MC bench: built-in Cornell scene {resolution[0]}x{resolution[1]}, {samples} spp, "
          f"{platform.processor() or platform.machine()}, {cores} core(s)")
    _run((32, 32), 1, 1, repeats=1)  # warm-up: imports, Embree device
    rows = {}
    for threads in sorted({1, cores}):
        stats = _run(resolution, samples, threads)
        rows[threads] = stats
        wall = stats["render_seconds"]
        paths = resolution[0] * resolution[1] * samples
        per_kind = ", ".join(f"{k} {v / wall / 1e6:.2f}" for k, v in stats["rays"].items())
        worker_seconds = wall * threads
        embree = stats["seconds_in_accelerator"] / worker_seconds
        analytic = (stats["seconds_in_intersection"] - stats["seconds_in_accelerator"]) / worker_seconds
        print(f"workers {threads} ({stats['parallelism']}): {wall:6.2f} s  {paths / wall / 1e3:8.1f} k paths/s  "
              f"{stats['rays_per_second'] / 1e6:5.2f} M rays/s  (M rays/s by kind: {per_kind})")
        print(f"           worker time: {embree * 100:5.1f} % inside Embree calls, {analytic * 100:5.1f} % in the rest "
              f"of intersection (NumPy sphere and quad kernels, merge), {(1 - embree - analytic) * 100:5.1f} % NumPy shading, "
              f"sampling and bookkeeping")
    if cores > 1:
        speedup = rows[1]["render_seconds"] / rows[cores]["render_seconds"]
        print(f"speed-up 1 -> {cores} workers: {speedup:.2f}x")
        rows["speedup"] = speedup
    best = rows[cores]
    print(f"per sample pass ({resolution[0]}x{resolution[1]}, one camera ray per pixel): "
          f"{best['render_seconds'] / samples * 1e3:.1f} ms with {cores} worker(s); "
          f"estimator {best['estimator']}, sampler {best['sampler']}")
    return rows


def _timed(resolution, samples, repeats, cluster=None):
    """Best of `repeats`: (wall seconds of the render() call, its stats); on the Dask scheduler at
    `cluster` when given (the pool is made inside the timed call, as the command line does)."""
    from ..pools.spec import make_pool
    best = None
    for _ in range(repeats):
        start = time.perf_counter()
        settings = RenderSettings(samples=samples)
        pool = make_pool(f"dask:{cluster}", settings.resolved_threads(), log=lambda *a: None) if cluster else None
        stats = render(cornell_scene(resolution), settings, pool=pool, log=lambda *a: None).stats
        wall = time.perf_counter() - start
        if best is None or wall < best[0]:
            best = (wall, stats)
    return best


def run_bench_cluster(resolution=(256, 256), samples=64, workers=2, repeats=3) -> float:
    """The same render on the local process pool and through a Dask cluster of `workers` one-thread
    worker processes started here on 127.0.0.1 (scheduler and workers as separate processes, as on
    a real cluster; their start-up is not timed).  Local and Dask renders alternate, so a change in
    the machine's load hits both; prints the best of each and the median of the pairs' ratios, and
    returns the best-of ratio dask time / local time."""
    from ..pools.dask_cluster import ProcessCluster
    cores = os.cpu_count() or 1
    print(f"TNCG15 MC bench-cluster: built-in Cornell scene {resolution[0]}x{resolution[1]}, {samples} spp, "
          f"{cores} core(s); {repeats} alternating pairs")
    _run((32, 32), 1, 1, repeats=1)                      # warm-up: imports, Embree device
    with tempfile.TemporaryDirectory(prefix="tncg15-bench-cluster-") as tmp:
        start = time.perf_counter()
        cluster = ProcessCluster(tmp, workers=workers)
        print(f"cluster: scheduler + {workers} workers at {cluster.address} up in {time.perf_counter() - start:.1f} s")
        try:
            _timed((32, 32), 1, 1, cluster=cluster.address)  # warm-up: worker imports
            pairs = [(_timed(resolution, samples, 1), _timed(resolution, samples, 1, cluster=cluster.address))
                     for _ in range(repeats)]
        finally:
            cluster.close()
    local_wall, local = min((p[0] for p in pairs), key=lambda x: x[0])
    dask_wall, dask = min((p[1] for p in pairs), key=lambda x: x[0])
    for name, wall, stats in (("local", local_wall, local), ("dask", dask_wall, dask)):
        print(f"{name:5s} {stats['parallelism']}: {wall:6.2f} s per render() call ({stats['render_seconds']:.2f} s "
              f"rendering {stats['units']} units), {stats['rays_per_second'] / 1e6:.2f} M rays/s")
    ratios = sorted(d[0] / l[0] for l, d in pairs)
    ratio = dask_wall / local_wall
    print(f"pairs dask / local: {' '.join(f'{r:.3f}' for r in ratios)} (median {ratios[len(ratios) // 2]:.3f})")
    print(f"dask / local (best of each): {ratio:.3f} ({(ratio - 1) * 100:+.1f} %; the bound is +10 %: docs/performance.md)")
    return ratio
