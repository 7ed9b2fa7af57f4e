"""Triangles through Embree (embreex), robust mode, whole batches per call."""
from __future__ import annotations

import logging

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from ...core.errors import SceneError
from ...core.vec import aos
from . import embree_buffers
from .rows import RowQueries

try:
    import resource                     # POSIX only: without it there is no RLIMIT_AS to check
except ImportError:                     # pragma: no cover - Windows
    resource = None

# embreex takes float32; +inf is a valid tfar but keep it finite for safety.
FLOAT32_FAR = np.float32(3.0e38)



# Address space Embree's triangle buffers and the build take, probed before TriangleMesh: when its
# buffers cannot be allocated it writes through a null pointer (rc 139) before any error can be
# read.  Measured: 1M triangles built under RLIMIT_AS with 170 MiB of room in the CLI process;
# unconstrained the build maps 190 MiB + 170 bytes per triangle (malloc arenas it then reuses).
PROBE_BYTES = 32 << 20
PROBE_BYTES_PER_TRIANGLE = 128


def probe_room(triangles: int) -> None:
    """SceneError when the address space Embree's buffers need cannot be mapped now (a mapping
    never touched: no memory is used)."""
    need = PROBE_BYTES + triangles * PROBE_BYTES_PER_TRIANGLE
    try:
        np.empty(need, np.uint8)
    except MemoryError:
        raise SceneError(_message(triangles, f"{need / 2**30:.2f} GB of address space could not be mapped")) from None


def _message(triangles: int, what: str) -> str:
    limit = address_space_limit()
    return (f"Embree cannot build the BVH of {triangles} triangles ({what})"
            + (f"; the address-space limit (RLIMIT_AS, ulimit -v) is {limit / 2**30:.1f} GB: raise it or"
               if limit else ":") + " use fewer triangles or threads")


class _Errors(logging.Handler):
    """Collects what embreex's error callback logs (it logs and returns: the scene stays unbuilt)."""

    def __init__(self):
        super().__init__(logging.ERROR)
        self.messages: list[str] = []

    def emit(self, record):
        self.messages.append(record.getMessage())


def build(scene, triangles: int) -> None:
    """Commit `scene` (embreex builds the BVH on its first query: here one with no rays) and raise
    SceneError in one line when Embree reports an error, before any ray meets the unbuilt scene,
    which crashes the process (Embree out of memory under RLIMIT_AS: rc 139)."""
    log = logging.getLogger("embreex")
    errors, propagate = _Errors(), log.propagate
    log.addHandler(errors)
    log.propagate = False
    try:
        scene.run(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32))
    finally:
        log.removeHandler(errors)
        log.propagate = propagate
    if errors.messages:
        what = "; ".join(m for m in errors.messages if not m.startswith("ERROR CAUGHT")) or errors.messages[0]
        raise SceneError(_message(triangles, what))


def address_space_limit() -> int | None:
    if resource is None:
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    return None if soft == resource.RLIM_INFINITY or soft < 0 else soft


class EmbreeAccelerator(RowQueries):
    ray_dtype = np.float32               # what intersect() and occluded() take
    name = "embree"
    compiled_rows = True                 # the queries on rows take embree_jit.py's loop (RowQueries)

    def __init__(self, triangles: np.ndarray):
        # RTC_SCENE_FLAG_ROBUST: no cracks along shared edges (docs/hard-cases.md H4).
        self.scene = rtcore_scene.EmbreeScene(robust=True)
        self.count = len(triangles)
        if self.count:
            probe_room(self.count)
            triangles = np.ascontiguousarray(triangles, dtype=np.float32)
            if embree_buffers.available():      # the same buffers as TriangleMesh, copied as arrays
                try:
                    embree_buffers.attach_triangles(self.scene, triangles)
                except MemoryError as exc:
                    raise SceneError(_message(self.count, str(exc))) from None
            else:
                TriangleMesh(self.scene, triangles)
            # Build the BVH now: the build uses Embree's thread pool, which a forked render worker
            # does not have.
            build(self.scene, self.count)

    def _tfar(self, tmax: np.ndarray) -> np.ndarray:
        # A fresh array: embreex overwrites `dists` in place (docs/hard-cases.md §1).
        return np.minimum(tmax, FLOAT32_FAR).astype(np.float32)

    def intersect(self, origins, directions, tmax):
        n = len(origins)
        if self.count == 0 or n == 0:
            return (np.full(n, np.inf), np.full(n, -1, dtype=np.int64),
                    np.zeros(n), np.zeros(n))
        result = self.scene.run(np.asarray(origins, np.float32), np.asarray(directions, np.float32),
                                dists=self._tfar(tmax), output=1)
        prim = result["primID"].astype(np.int64)
        hit = prim >= 0
        t = np.where(hit, result["tfar"].astype(np.float64), np.inf)
        return t, np.where(hit, prim, -1), result["u"].astype(np.float64), result["v"].astype(np.float64)

    def intersect_rows(self, o, d, tmax, compiled=None):
        """intersect() of the rays as (3, N) float64 rows: through embreex on float32 copies, or with
        `compiled` (engine/geometry/accel/embree_jit.py, bound) Embree called on the rows themselves:
        the same answers."""
        if compiled is None or self.count == 0 or o.shape[1] == 0:
            return self.intersect(aos(o, np.float32), aos(d, np.float32), tmax)
        return compiled.intersect(self.handle(), o, d, tmax)

    def nearest_rows(self, o, d, t, compiled=None):
        """(t, kind, prim, u, v): the bounds t (float64, written in place) lowered to the triangle hits
        nearer than them, kind 1 (TRIANGLE) there else 0, prim the triangle there else -1, and u, v of
        intersect(), for SceneGeometry.intersect: as NumPy below, or in the compiled loop itself."""
        if compiled is not None and self.count and o.shape[1]:
            return compiled.nearest(self.handle(), o, d, t)
        tt, tp, u, v = self.intersect_rows(o, d, t, compiled)
        closer = tt < t
        t[:] = np.where(closer, tt, t)
        return t, closer.astype(np.int8), np.where(closer, tp, -1), u, v

    def occluded_rows(self, o, d, tmax, compiled=None):
        """occluded() of the rays as (3, N) float64 rows (as intersect_rows)."""
        if compiled is None or self.count == 0 or o.shape[1] == 0:
            return self.occluded(aos(o, np.float32), aos(d, np.float32), tmax)
        return compiled.occluded(self.handle(), o, d, tmax)

    def handle(self) -> int:
        """The RTCScene of this accelerator's scene (embree_buffers.scene_handle)."""
        return embree_buffers.scene_handle(self.scene)

    def occluded(self, origins, directions, tmax):
        n = len(origins)
        if self.count == 0 or n == 0:
            return np.zeros(n, dtype=bool)
        ids = self.scene.run(np.asarray(origins, np.float32), np.asarray(directions, np.float32),
                             dists=self._tfar(tmax), query="OCCLUDED")
        return ids >= 0
