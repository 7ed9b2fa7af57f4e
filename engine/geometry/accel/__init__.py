"""Triangle accelerators behind one interface.

An accelerator is built from a (T, 3, 3) float64 array of world-space triangles and
answers, for arrays of rays:

    intersect(origins, directions, tmax) -> (t, prim, u, v)
        t: float64, +inf on a miss; prim: int64 triangle index, -1 on a miss;
        u, v: barycentrics of vertices 1 and 2.
    occluded(origins, directions, tmax) -> bool array

Every accelerator also answers for rays as (3, N) float64 rows (`nearest_rows`, `occluded_rows`:
rows.py RowQueries, through the two above on copies); the Embree accelerator's (and its
`intersect_rows`) go through embreex on float32 copies, or, given the compiled loop of embree_jit.py
(backend numba, `compiled_rows`), call Embree on the rows themselves; the same answers.

Rays start at t = 0 (embreex cannot set tnear): callers offset the origins.
Spheres and quads are not in the accelerator (embreex takes triangles only): they are
tested analytically in every mode, one after the other or, beyond a few, through their own
hierarchy (engine/geometry/shapes/box_tree.py, engine/geometry/scene_geometry.py).

Modes: "embree" (embreex, float32, robust mode), "octree" (the report's octree in
Python + NumPy), "brute" (every ray against every triangle: the report's "no octree").

A process keeps the last accelerator it built (`build_accelerator`): a scene prepared again with the
same triangles (a light, material or camera edit in the viewport; an animation frame in which no mesh
moved, with Persistent Data) reuses it instead of building the BVH again.  Accelerators are
read-only once built, so sharing one between prepared scenes changes no hit.
"""
from __future__ import annotations

import numpy as np

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


_last_built = []        # [(name, triangles, accelerator)]: the last one built in this process


def build_accelerator(name: str, triangles):
    """The accelerator `name` over `triangles` (T, 3, 3): the last one built when its name and
    triangles are the same (element for element), else a new one (which then is the last)."""
    if _last_built:
        last_name, last_triangles, accelerator = _last_built[0]
        if last_name == name and last_triangles.shape == triangles.shape and np.array_equal(last_triangles, triangles):
            return accelerator
    _last_built.clear()                 # the old BVH is freed before the new one is built
    accelerator = ACCELERATOR_CLASSES[name](triangles)
    # kept by reference (no second copy of a big mesh): nothing writes into a built scene's triangles
    _last_built.append((name, triangles, accelerator))
    return accelerator
