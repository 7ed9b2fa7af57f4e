"""3-vectors of a batch as rows: (3, N) arrays, x, y and z each contiguous (struct of arrays).

Why rows: on this project's machines NumPy is slow on the short last axis of (N, 3)
arrays.  For 25,000 vectors, `u[:, None] * e` takes 173 us against 57 us for rows,
`e * colour` with a (3,) colour 212 us against 21 us, and a row-wise dot product with
strided components several times the time of contiguous ones.  The tracer keeps every
per-ray vector as rows; a single vector (a sphere centre, a colour) is a (3,) array,
and `vector[:, None]` broadcasts it over rows.

The triangle accelerators take (N, 3) arrays (Embree: float32); `aos` builds one in
a single pass.
"""
from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-ray dot product of rows (either may be a single (3,) vector)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def norm(a: np.ndarray) -> np.ndarray:
    return np.sqrt(dot(a, a))


def normalize(a: np.ndarray) -> np.ndarray:
    return a / norm(a)


def max3(a: np.ndarray) -> np.ndarray:
    """Largest component of each vector."""
    return np.maximum(np.maximum(a[0], a[1]), a[2])


def max_abs3(a: np.ndarray) -> np.ndarray:
    """Largest absolute component of each vector (the scale of a position)."""
    return np.maximum(np.maximum(np.abs(a[0]), np.abs(a[1])), np.abs(a[2]))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-ray cross product of rows; either argument may be a single (3,) vector."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """cross(a, b) of two (3, N) float64 rows, written into one new array (the same values; no
    np.stack of three temporaries: 2.7 -> 1 ms for 93k triangles)."""
    out = np.empty((3, a.shape[1]))
    for k, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
        np.subtract(a[i] * b[j], a[j] * b[i], out=out[k])
    return out


def rows(vectors) -> np.ndarray:
    """(3, N) float64 rows from (N, 3) vectors (the layout of scene data and tests)."""
    return np.ascontiguousarray(np.asarray(vectors, dtype=np.float64).reshape(-1, 3).T)


def aos(a: np.ndarray, dtype=np.float64) -> np.ndarray:
    """(N, 3) C-contiguous vectors from rows (for Embree: dtype float32)."""
    out = np.empty((a.shape[1], 3), dtype=dtype)
    out[:, 0], out[:, 1], out[:, 2] = a[0], a[1], a[2]
    return out


def triangle_rows(vertices: np.ndarray, triangles: np.ndarray):
    """Rows (3, T) of the first corner v0 and the edges v1 - v0, v2 - v0 of indexed triangles
    ((V, 3) vertices, (T, 3) corner indices), and each triangle's largest absolute coordinate (T,):
    the values of ``v = vertices[triangles]; v[:, 0], v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]`` and
    ``np.abs(v).max(axis=(1, 2))`` bit for bit (the same subtractions; a maximum is exact in any
    order), without (T, 3) arrays whose short last axis NumPy is slow on (a third of the time for
    93k triangles)."""
    coords = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)       # (3, V)
    return _rows_of(coords, max_abs3(coords), triangles)


def _rows_of(coords: np.ndarray, corner: np.ndarray, triangles: np.ndarray):
    """triangle_rows of `triangles` from the vertices as rows (3, V) and their largest absolute
    coordinates (V,)."""
    i0, i1, i2 = (np.ascontiguousarray(triangles[:, k]) for k in range(3))
    v0 = coords.take(i0, axis=1)
    e1, e2 = coords.take(i1, axis=1) - v0, coords.take(i2, axis=1) - v0
    scale = np.maximum(np.maximum(corner.take(i0), corner.take(i1)), corner.take(i2))
    return v0, e1, e2, scale


ROWS_CHUNK = 8192                 # triangles per piece of triangle_rows_chunks


def triangle_rows_chunks(vertices: np.ndarray, triangles: np.ndarray, size: int = ROWS_CHUNK):
    """triangle_rows of consecutive pieces of `size` triangles, the same values element for
    element: (first triangle, (v0, e1, e2, scale)) for each piece.  For a caller that needs the
    rows only for a moment (a mesh's validation, once per frame of an animation): a piece's
    temporaries are a few 100 kB that the allocator hands out again for the next piece, where
    whole-mesh rows (2.2 MB each for 93k triangles, about 25 MB in all) are fresh memory that an
    allocator returning freed pages to the system between frames (Blender 3.4's jemalloc)
    page-faults in again: 2,000-4,000 page faults and 8-20 CPU ms of every frame's validation."""
    coords = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).T)       # (3, V)
    corner = max_abs3(coords)
    for start in range(0, len(triangles), size):
        yield start, _rows_of(coords, corner, triangles[start:start + size])


def gather(a: np.ndarray, index: np.ndarray) -> np.ndarray:
    """a.take(index, axis=-1) for per-object arrays ((K,) or rows (3, K)); with one object the
    array itself, which broadcasts against per-ray arrays without a copy."""
    return a if a.shape[-1] == 1 else a.take(index, axis=-1)
