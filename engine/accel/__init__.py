"""Triangle accelerators behind one interface.

An accelerator is built from a (T, 3, 3) float64 array of world-space triangles and
answers, for arrays of rays:

    intersect(origins, directions, tmax) -> (t, prim, u, v)
        t: float64, +inf on a miss; prim: int64 triangle index, -1 on a miss;
        u, v: barycentrics of vertices 1 and 2.
    occluded(origins, directions, tmax) -> bool array

Rays start at t = 0 (embreex cannot set tnear): callers offset the origins.
"""
from __future__ import annotations

from .embree import EmbreeAccelerator

ACCELERATOR_CLASSES = {"embree": EmbreeAccelerator}


def choose_accelerator(name: str, triangle_count: int) -> tuple[str, str]:
    """Resolve 'auto' to a concrete accelerator; returns (name, reason)."""
    if name != "auto":
        return name, f"'{name}' requested"
    return "embree", f"auto: Embree is fastest here at every size ({triangle_count} triangles)"


def build_accelerator(name: str, triangles):
    return ACCELERATOR_CLASSES[name](triangles)
