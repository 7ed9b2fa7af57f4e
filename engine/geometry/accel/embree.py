"""Triangles through Embree (embreex), robust mode, whole batches per call."""
from __future__ import annotations

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from ...core.errors import SceneError

try:
    import resource                     # POSIX only: without it there is no RLIMIT_AS to check
except ImportError:                     # pragma: no cover - Windows
    resource = None

# embreex takes float32; +inf is a valid tfar but keep it finite for safety.
FLOAT32_FAR = np.float32(3.0e38)

# Address space a BVH build maps (measured on this build: VmPeak over VmSize before the build,
# 200k-2M triangles, about 190 MiB + 170 bytes per triangle; engine/rendering/memory.py).  Embree
# out of memory prints "Out of memory" and the process then crashes, so a build that cannot fit
# under RLIMIT_AS is refused before it starts.
BUILD_ADDRESS_BYTES = 256 << 20
BUILD_ADDRESS_BYTES_PER_TRIANGLE = 200


def check_build_fits(triangles: int, status: str = "/proc/self/status") -> None:
    """SceneError when a BVH of `triangles` would not fit under RLIMIT_AS (one line, not a crash)."""
    if resource is None:
        return
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY or soft < 0:
        return
    mapped = 0
    try:
        with open(status) as fh:
            mapped = next((int(line.split()[1]) * 1024 for line in fh if line.startswith("VmSize:")), 0)
    except (OSError, ValueError, IndexError):
        pass
    need = mapped + BUILD_ADDRESS_BYTES + triangles * BUILD_ADDRESS_BYTES_PER_TRIANGLE
    if need > soft:
        raise SceneError(f"Embree's BVH of {triangles} triangles needs about {need / 2**30:.1f} GB of address space, "
                         f"the limit (RLIMIT_AS, ulimit -v) is {soft / 2**30:.1f} GB: raise the limit or use fewer "
                         f"triangles")


class EmbreeAccelerator:
    ray_dtype = np.float32               # what intersect() and occluded() take
    name = "embree"

    def __init__(self, triangles: np.ndarray):
        # RTC_SCENE_FLAG_ROBUST: no cracks along shared edges (docs/hard-cases.md H4).
        self.scene = rtcore_scene.EmbreeScene(robust=True)
        self.count = len(triangles)
        if self.count:
            check_build_fits(self.count)
            TriangleMesh(self.scene, np.ascontiguousarray(triangles, dtype=np.float32))
            # Build the BVH now (embreex commits on the first query): the build uses Embree's
            # thread pool, which a forked render worker does not have.
            self.scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))

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

    def occluded(self, origins, directions, tmax):
        n = len(origins)
        if self.count == 0 or n == 0:
            return np.zeros(n, dtype=bool)
        ids = self.scene.run(np.asarray(origins, np.float32), np.asarray(directions, np.float32),
                             dists=self._tfar(tmax), query="OCCLUDED")
        return ids >= 0
