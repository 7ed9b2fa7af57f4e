"""engine/nodes/context.py's object-space attributes compiled with numba: the hits' points in object space
(`object_points`, Texture Coordinate's Object) and mapped to the object's texture space (`generated`,
its Generated), each in one loop over the points instead of NumPy's thirteen (object_points) and four
(generated) passes over (3, N) arrays.  Imported only through engine/core/backend.py's choice (it imports
numba; kernel name "textures", the scene lookups' choice); SceneAttributes (context.py) calls it when
HitTextures (engine/materials/textures.py) hands it this module.

The float operations are context.py's, in its order: object_points's row i is
((m[i, a] p[a] + m[i, b] p[b]) + m[i, c] p[c]) + m[i, 3], then + 0.0, with (a, b, c) = (0, 1, 2) for
points whose components lie apart (rows) and (0, 2, 1) for points whose components are adjacent (the
(k, 3) form's transpose), as NumPy's einsum sums them (context.py object_points and
components_adjacent; other layouts stay on that einsum); generated is (o - centre) / (2 size) + 0.5.
The same numbers bit for bit (tests/nodes/test_context_jit.py)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from ..core.kernel_inputs import contiguous

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _object_points(m, points, adjacent, out):
    """m (1 or k, 3, 4); points (3, k) rows, or (k, 3) when `adjacent` (the components of a point
    together); out (3, k), filled row by row (contiguous writes)."""
    k = out.shape[1]
    one = m.shape[0] == 1
    second, third = (2, 1) if adjacent else (1, 2)
    for i in range(3):
        row = out[i]
        for j in range(k):
            r = 0 if one else j
            if adjacent:
                pa, pb, pc = points[j, 0], points[j, second], points[j, third]
            else:
                pa, pb, pc = points[0, j], points[second, j], points[third, j]
            v = m[r, i, 0] * pa
            v += m[r, i, second] * pb
            v += m[r, i, third] * pc
            v += m[r, i, 3]
            row[j] = v + 0.0


def object_points(m, points, adjacent: bool) -> np.ndarray:
    """context.object_points compiled: m (k or 1, 3, 4) world-to-object matrices, points rows (3, k)
    (float64) whose components are adjacent or not (context.components_adjacent: True / False; the
    caller keeps other layouts on NumPy's einsum) -> the object-space rows (3, k), the same numbers."""
    k = points.shape[1]
    if m.shape[0] not in (1, k):
        raise ValueError(f"{m.shape[0]} matrices for {k} points")
    out = np.empty((3, k))
    _object_points(contiguous(m), contiguous(points.T if adjacent else points), adjacent, out)
    return out


@jit
def _generated(o, centre, size, out):
    """o (3, k); centre, size (1 or k, 3) (one object's, or each point's); out (3, k), row by row."""
    k = out.shape[1]
    one = centre.shape[0] == 1
    for i in range(3):
        row, oi = out[i], o[i]
        for j in range(k):
            r = 0 if one else j
            row[j] = (oi[j] - centre[r, i]) / (2.0 * size[r, i]) + 0.5


def generated(o, centre, size) -> np.ndarray:
    """(o - centre.T) / (2 size.T) + 0.5 for object-space rows o (3, k) and the objects' texture-space
    centres and half sizes centre, size (1 or k, 3): context.py's Generated, rows (3, k) C-ordered."""
    k = o.shape[1]
    if not (centre.shape == size.shape and centre.shape[0] in (1, k) and centre.shape[1:] == (3,)):
        raise ValueError(f"{centre.shape[0]} centres and {size.shape[0]} sizes for {k} points")
    out = np.empty(o.shape)
    _generated(contiguous(o), contiguous(centre), contiguous(size), out)
    return out


def warm_up() -> None:
    """Compile the kernels for the types a render passes (engine/core/backend.py)."""
    m = np.tile(np.eye(4)[:3], (1, 1, 1))
    for points in (np.zeros((3, 4)), np.zeros((4, 3)).T):
        object_points(m, points, points.strides[0] == points.itemsize)
    generated(np.zeros((3, 4)), np.zeros((1, 3)), np.ones((1, 3)))
