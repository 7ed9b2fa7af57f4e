"""Memory a render needs, estimated before anything large is allocated, and refused with a
message when the machine (or the process's limits) does not have it, instead of being killed
half-way, swapping, or crashing inside Embree.

Where the copies are.  Threads and forked processes (engine/pools/local.py) share one prepared
scene: it is built in this process, and forked workers read it copy-on-write.  Worker processes
(engine/pools/processes.py, the add-on's pool) each unpickle their own scene and build their own
geometry tables and Embree BVH, so the scene is held once per worker plus once here (with the
pickled message for each worker).  A Dask cluster's workers are on other machines: only this
process's share is counted.

The figures were measured on this build (NumPy 2, embreex 4 / Embree 4, Python 3.11, 2 cores)
with `python -m engine bench-memory` (engine/cli/bench_memory.py: peak VmHWM of every process
of a render, summed; 200k-1M triangles, 64²-2048²) and are documented with its table in
docs/performance.md:
* PROCESS_BYTES: a Python that has imported the tracer (NumPy, embreex): about 50 MiB;
* WORKER_BYTES: what tracing adds per worker (wavefront of 65,536 paths and its temporaries,
  the tile's film): about 72 MiB (a one-worker 256², 64 spp Cornell render's VmHWM over the
  prepared scene's: 73 MiB; 45 MiB with the former wavefront of 32,768 paths);
* BYTES_PER_PIXEL: the frame's film (sums, squares, counts, half buffers, variance) and the
  result image, held where the render was asked for; writing EXR and PNG adds nothing above it
  (a 2048² CLI render: 1.03 GiB peak against 0.09 GiB at 256²): about 240 bytes;
* SCENE_BYTES_PER_TRIANGLE: a scene's mesh arrays (float64 vertices, indices, material ids): 64;
* MESSAGE_BYTES_PER_TRIANGLE: the pickled scene sent to each worker process: 44;
* TRACING_BYTES_PER_TRIANGLE: a prepared scene's geometry tables and Embree's BVH after the build
  (the BVH alone about 90 bytes): 360;
* BUILD_BYTES_PER_TRIANGLE: freed when the build ends (Embree's build arrays, float32 copies): 100.
  The peak of a tracing process is the larger of the build and the render that follows it;
* BYTES_PER_SMOOTH_TRIANGLE: corner normals in the scene and the geometry's table: 160 more;
* ADDRESS_SPACE_BYTES: address space a tracing process maps beyond what it touches (shared
  libraries, thread stacks, Embree's reservations): 256 MiB, compared with RLIMIT_AS, which limits
  each process on its own.  Unconstrained, VmPeak - VmHWM is 350-420 MiB, but under a limit malloc
  reuses its arenas: the CLI rendered 1M triangles with 2 forked workers under 858 MiB of RLIMIT_AS
  (estimate 535 MiB) and not under 763 MiB.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

from ..core.errors import SceneError
from ..geometry.shading_normals import has_smooth

MIB = 1 << 20
PROCESS_BYTES = 50 * MIB
WORKER_BYTES = 72 * MIB
BYTES_PER_PIXEL = 240
SCENE_BYTES_PER_TRIANGLE = 64
MESSAGE_BYTES_PER_TRIANGLE = 44
TRACING_BYTES_PER_TRIANGLE = 360
BUILD_BYTES_PER_TRIANGLE = 100
BYTES_PER_SMOOTH_TRIANGLE = 160
ADDRESS_SPACE_BYTES = 256 * MIB
UNLIMITED = 1 << 60                       # limits at or above this mean "none"

SHARED_POOLS = ("auto", "threads", "processes")   # one prepared scene in this process
OWN_COPY_POOLS = ("workers", "viewport")          # each worker process prepares its own
REMOTE_POOLS = ("dask",)                          # workers elsewhere


@dataclass
class MemoryEstimate:
    """Peak bytes of this process and of each worker process holding its own scene."""
    main: int
    per_worker: int = 0
    worker_processes: int = 0

    @property
    def total(self) -> int:
        return self.main + self.per_worker * self.worker_processes

    @property
    def largest_process(self) -> int:
        return max(self.main, self.per_worker)


def memory_estimate(scene, settings, pool: str | None = None) -> MemoryEstimate:
    """The estimate for `scene` rendered with `settings` on a pool of kind `pool` (a spec's kind:
    threads, processes, workers, viewport, dask; default settings.parallelism)."""
    kind = str(pool or settings.parallelism).partition(":")[0]
    width, height = (int(v) for v in scene.resolution)
    pixels = width * height * BYTES_PER_PIXEL
    workers = settings.resolved_threads()
    triangles = sum(len(m.triangles) for m in scene.meshes)
    scene_bytes = triangles * SCENE_BYTES_PER_TRIANGLE
    prepared = triangles * TRACING_BYTES_PER_TRIANGLE + has_smooth(scene.meshes) * BYTES_PER_SMOOTH_TRIANGLE
    build = triangles * BUILD_BYTES_PER_TRIANGLE
    if kind in OWN_COPY_POOLS or kind in REMOTE_POOLS:
        senders = workers if kind in OWN_COPY_POOLS else 1
        main = PROCESS_BYTES + scene_bytes + senders * triangles * MESSAGE_BYTES_PER_TRIANGLE + pixels
        if kind in REMOTE_POOLS:
            return MemoryEstimate(main)
        per_worker = PROCESS_BYTES + scene_bytes + prepared + max(build, WORKER_BYTES)
        return MemoryEstimate(main, per_worker, workers)
    return MemoryEstimate(PROCESS_BYTES + scene_bytes + prepared + max(build, pixels + workers * WORKER_BYTES))


def estimate_bytes(scene, settings, pool: str | None = None) -> int:
    """The summed peak of every local process of the render, in bytes."""
    return memory_estimate(scene, settings, pool).total


# -- limits ---------------------------------------------------------------------------------------
def _read(path: str) -> str | None:
    try:
        with open(path) as fh:
            return fh.read()
    except OSError:
        return None


def _number(text: str | None) -> int | None:
    """A limit file's number; None for "max", garbage, or a value meaning unlimited."""
    try:
        value = int(str(text).strip())
    except ValueError:
        return None
    return value if 0 <= value < UNLIMITED else None


def mem_available(proc: str = "/proc") -> int | None:
    """MemAvailable from /proc/meminfo (Linux), else free physical pages; None when unknown."""
    for line in (_read(f"{proc}/meminfo") or "").splitlines():
        if line.startswith("MemAvailable:"):
            try:
                return int(line.split()[1]) * 1024
            except (ValueError, IndexError):
                break
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def cgroup_room(proc: str = "/proc", cgroup: str = "/sys/fs/cgroup") -> int | None:
    """Bytes this process's memory cgroup still allows (limit - usage); None without a limit.
    cgroup v2: <cgroup>/<path>/memory.max and memory.current; v1: <cgroup>/memory/<path>/
    memory.limit_in_bytes and memory.usage_in_bytes (the path from <proc>/self/cgroup)."""
    for line in (_read(f"{proc}/self/cgroup") or "").splitlines():
        parts = line.strip().split(":", 2)
        if len(parts) != 3:
            continue
        _, controllers, path = parts
        path = path.strip("/")
        if controllers == "":
            root, files = cgroup, ("memory.max", "memory.current")
        elif "memory" in controllers.split(","):
            root, files = os.path.join(cgroup, "memory"), ("memory.limit_in_bytes", "memory.usage_in_bytes")
        else:
            continue
        # in a container the path is the host's and the container's own cgroup is mounted at the root
        for base in dict.fromkeys((os.path.join(root, path), root)):
            text = _read(os.path.join(base, files[0]))
            if text is None:
                continue
            limit = _number(text)
            if limit is not None:
                return max(0, limit - (_number(_read(os.path.join(base, files[1]))) or 0))
            break
    return None


def address_space_limit() -> int | None:
    """RLIMIT_AS (soft) in bytes; None when unlimited or unknown."""
    try:
        import resource
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, ValueError, OSError):
        return None
    return None if soft == resource.RLIM_INFINITY or soft < 0 or soft >= UNLIMITED else soft


def memory_limits(proc: str = "/proc", cgroup: str = "/sys/fs/cgroup") -> list[tuple[int, str]]:
    """The limits on the render's summed memory: (bytes, what) for MemAvailable and the cgroup."""
    found = [(mem_available(proc), "MemAvailable"), (cgroup_room(proc, cgroup), "the cgroup's memory limit")]
    return [(n, what) for n, what in found if n is not None]


def available_bytes() -> int | None:
    """The smallest of MemAvailable and the cgroup's room; None when unknown."""
    limits = memory_limits()
    return min(n for n, _ in limits) if limits else None


def gigabytes(n: int) -> str:
    return f"{n / 2**30:.1f} GB"


def check_memory(scene, settings, available: int | None = None, pool: str | None = None,
                 address_limit: int | None = None) -> int:
    """The estimate in bytes; SceneError naming the scene, the figure and the limit when the
    render needs more than MemAvailable, the cgroup's room, or (per process) RLIMIT_AS allow."""
    estimate = memory_estimate(scene, settings, pool)
    need = estimate.total
    w, h = scene.resolution
    advice = "use fewer threads (--threads) or a lower resolution"
    limits = [(available, "available")] if available is not None else memory_limits()
    if limits:
        room, what = min(limits)
        if need > room:
            source = "" if what == "available" else f" ({what})"
            raise SceneError(f"Scene '{scene.name}': a {w}x{h} render needs about {gigabytes(need)} of memory, "
                             f"only {gigabytes(room)} is available{source}: with {settings.resolved_threads()} "
                             f"worker(s); {advice}")
    address_limit = address_space_limit() if address_limit is None else address_limit
    process = estimate.largest_process + ADDRESS_SPACE_BYTES
    if address_limit is not None and process > address_limit:
        raise SceneError(f"Scene '{scene.name}': a {w}x{h} render needs about {gigabytes(process)} of address "
                         f"space in one process, the limit (RLIMIT_AS, ulimit -v) is {gigabytes(address_limit)}: "
                         f"raise the limit, {advice}")
    return need
