"""Memory a render needs, estimated before anything large is allocated, and refused with a
message when the machine does not have it (instead of being killed half-way, or swapping).

The figures are upper bounds per unit, measured loosely on this tracer:
* per image pixel: the image and variance (float32), the written copies and the sRGB encode
  of a PNG (float64 temporaries): about 120 bytes;
* per worker: its tile film (sum, sum of squares, count in float64) twice (the copy sent back),
  and the wavefront of 32,768 paths with their temporaries: about 64 MB;
* per triangle: float64 and float32 copies and the acceleration structure: about 256 bytes;
* per smooth-shaded triangle: its 3 corner normals in the scene and in the geometry's table
  (float64) and the table's index: about 160 bytes more.
"""
from __future__ import annotations

import os

from ..core.errors import SceneError
from ..geometry.shading_normals import has_smooth

BYTES_PER_PIXEL = 120
BYTES_PER_TILE_PIXEL = 2 * 7 * 8
BYTES_PER_WORKER = 64 << 20
BYTES_PER_TRIANGLE = 256
BYTES_PER_SMOOTH_TRIANGLE = 160


def estimate_bytes(scene, settings) -> int:
    width, height = (int(v) for v in scene.resolution)
    workers = settings.resolved_threads()
    tile = min(settings.tile_size, width) * min(settings.tile_size, height)
    triangles = sum(len(m.triangles) for m in scene.meshes)
    return (width * height * BYTES_PER_PIXEL + workers * (tile * BYTES_PER_TILE_PIXEL + BYTES_PER_WORKER)
            + triangles * BYTES_PER_TRIANGLE + has_smooth(scene.meshes) * BYTES_PER_SMOOTH_TRIANGLE)


def available_bytes() -> int | None:
    """MemAvailable from /proc/meminfo (Linux), else free physical pages; None when unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def gigabytes(n: int) -> str:
    return f"{n / 2**30:.1f} GB"


def check_memory(scene, settings, available: int | None = None) -> int:
    """The estimate in bytes; SceneError naming the scene when more than is available."""
    need = estimate_bytes(scene, settings)
    available = available_bytes() if available is None else available
    if available is not None and need > available:
        w, h = scene.resolution
        raise SceneError(f"Scene '{scene.name}': a {w}x{h} render needs about {gigabytes(need)} of memory, "
                         f"only {gigabytes(available)} is available (lower the resolution or the threads)")
    return need
