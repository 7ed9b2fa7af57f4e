"""Row-wise 3-vector helpers for (N, 3) arrays.

NumPy reduces slowly along a short last axis: on this project's machines
`a.max(axis=1)` on (32768, 3) takes ~1.8 ms and `np.einsum('ij,ij->i')` ~0.3 ms,
while the same work written per component takes 0.25 and 0.15 ms.  The hot paths
use these helpers instead.
"""
from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def norm(a: np.ndarray) -> np.ndarray:
    return np.sqrt(dot(a, a))


def normalize(a: np.ndarray) -> np.ndarray:
    return a / norm(a)[:, None]


def max3(a: np.ndarray) -> np.ndarray:
    """Largest component of each row."""
    return np.maximum(np.maximum(a[:, 0], a[:, 1]), a[:, 2])


def max_abs3(a: np.ndarray) -> np.ndarray:
    """Largest absolute component of each row (the scale of a position)."""
    return np.maximum(np.maximum(np.abs(a[:, 0]), np.abs(a[:, 1])), np.abs(a[:, 2]))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product; either argument may be a single 3-vector."""
    a = np.asarray(a)
    b = np.asarray(b)
    ax, ay, az = (a[..., 0], a[..., 1], a[..., 2])
    bx, by, bz = (b[..., 0], b[..., 1], b[..., 2])
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)
