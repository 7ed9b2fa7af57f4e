"""Triangle accelerators behind one interface.

An accelerator is built from a (T, 3, 3) float64 array of world-space triangles and
answers, for arrays of rays:

    intersect(origins, directions, tmax) -> (t, prim, u, v)
        t: float64, +inf on a miss; prim: int64 triangle index, -1 on a miss;
        u, v: barycentrics of vertices 1 and 2.
    occluded(origins, directions, tmax) -> bool array

Rays start at t = 0 (embreex cannot set tnear): callers offset the origins.
Spheres and quads are not in the accelerator (embreex takes triangles only): they are
tested analytically in every mode, one after the other or, beyond a few, through their own
hierarchy (engine/geometry/shapes/box_tree.py, engine/geometry/scene_geometry.py).

Modes: "embree" (embreex, float32, robust mode), "octree" (the report's octree in
Python + NumPy), "brute" (every ray against every triangle: the report's "no octree").
"""
from __future__ import annotations

from .brute import BruteForceAccelerator
from .octree import OctreeAccelerator

try:
    from .embree import EmbreeAccelerator
    EMBREE_ERROR = None
except ImportError as exc:  # embreex has wheels for few platforms
    EmbreeAccelerator = None
    EMBREE_ERROR = str(exc)

ACCELERATOR_CLASSES = {"embree": EmbreeAccelerator, "octree": OctreeAccelerator,
                       "brute": BruteForceAccelerator}

# Embree is faster than both others at every size; without Embree, brute force and the
# octree tie up to about 12 triangles and the octree wins above (measured:
# docs/performance.md, "Accelerators").
BRUTE_FORCE_MAX_TRIANGLES = 12


def choose_accelerator(name: str, triangle_count: int) -> tuple[str, str]:
    """Resolve 'auto' to a concrete accelerator; returns (name, reason)."""
    if name == "embree" and EmbreeAccelerator is None:
        from ...core.errors import SceneError
        raise SceneError(f"accelerator 'embree' is not available: {EMBREE_ERROR}")
    if name != "auto":
        return name, f"'{name}' requested"
    if EmbreeAccelerator is not None:
        return "embree", f"auto: Embree measured fastest at every size ({triangle_count} triangles)"
    if triangle_count <= BRUTE_FORCE_MAX_TRIANGLES:
        return "brute", (f"auto: Embree unavailable; {triangle_count} triangles <= "
                         f"{BRUTE_FORCE_MAX_TRIANGLES}, where an octree does not pay")
    return "octree", f"auto: Embree unavailable; {triangle_count} triangles: octree"


def build_accelerator(name: str, triangles):
    return ACCELERATOR_CLASSES[name](triangles)
