"""Implicit spheres (report 2.2.1), vectorised over rays: one sphere for every ray, or one sphere
per ray (the (ray, sphere) pairs of engine/geometry/shapes/box_tree.py).

The quadratic (eq. 2.3-2.5) is solved in the numerically stable form of Ray Tracing
Gems ch. 7 (also pbrt-v4's Sphere): the discriminant is formed from the squared
distance between the centre and the ray's line, r^2 - |v|^2 = (r + |v|)(r - |v|), and the
second root comes from t0 * t1 = C / A.  This keeps a 1e-3 sphere at 1e4 units exact
to ~1e-9 r where the textbook form misclassifies rays at 1.001 r (docs/hard-cases.md H9-H10).
"""
from __future__ import annotations

import numpy as np

from ...core.vec import dot, max_abs3, norm

EPS64 = np.finfo(np.float64).eps


def intersect_sphere(o: np.ndarray, d: np.ndarray, center: np.ndarray,
                     radius: float, t_best: np.ndarray | None = None) -> np.ndarray:
    """Nearest t > 0 of each ray (rows, see engine/core/vec.py) with one sphere; +inf if none.
    center (3,) and radius a number, or rows (3, N) and (N,): each ray's own sphere.

    A cheap test on the textbook discriminant first discards rays that clearly miss
    (or whose sphere lies beyond t_best); the stable solve runs on the rest only.
    """
    n = o.shape[1]
    t_out = np.full(n, np.inf)
    fx, fy, fz = o[0] - center[0], o[1] - center[1], o[2] - center[2]
    half_b = fx * d[0] + fy * d[1] + fz * d[2]
    c = fx * fx + fy * fy + fz * fz - radius * radius                # eq. 2.5c
    # Unit directions: B^2 - 4AC = 4 (half_b^2 - c).  Keep a generous margin so the
    # pre-test never rejects a ray the stable solve would accept.
    maybe = (half_b * half_b - c) >= -1e-6 * radius * radius
    maybe &= (c <= 0.0) | (half_b <= 0.0)                            # not outside and moving away
    if t_best is not None:
        maybe &= (-half_b - radius) < t_best                         # sphere not beyond best hit
    idx = np.flatnonzero(maybe)
    if len(idx) == 0:
        return t_out
    dd = d.take(idx, axis=1)
    f = np.stack([fx.take(idx), fy.take(idx), fz.take(idx)])
    a = dot(dd, dd)                                                  # eq. 2.5a
    b = 2.0 * half_b.take(idx)                                       # eq. 2.5b
    c = c.take(idx)
    if np.ndim(radius):
        radius = radius.take(idx)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = f - (0.5 * b / a) * dd
        length = np.sqrt(dot(v, v))
        discriminant = 4.0 * a * (radius + length) * (radius - length)   # B^2 - 4AC
        root = np.sqrt(np.maximum(discriminant, 0.0))
        q = -0.5 * (b + np.copysign(root, b))
        t0 = q / a                                                # eq. 2.4, stable pair
        t1 = c / q
    near = np.minimum(t0, t1)
    far = np.maximum(t0, t1)
    t = np.where(near > 0.0, near, far)
    valid = (discriminant >= 0.0) & (t > 0.0) & np.isfinite(t)
    t_out[idx] = np.where(valid, t, np.inf)
    return t_out


def sphere_kernel(backend: str = "numpy"):
    """intersect_sphere of a backend (engine/core/backend.py): this module's, or its compiled twin
    (engine/geometry/shapes/spheres_jit.py, the same t)."""
    if backend == "numba":
        from .spheres_jit import intersect_sphere as compiled
        return compiled
    return intersect_sphere


def sphere_loop_kernels(backend: str = "numpy"):
    """(nearest_spheres, occluded_by_spheres) of the compiled twin (engine/geometry/shapes/spheres_jit.py):
    every sphere against a ray in one loop, the numbers of engine/geometry/scene_geometry.py's loop
    over the spheres; None on the NumPy backend (that loop runs)."""
    if backend == "numba":
        from .spheres_jit import nearest_spheres, occluded_by_spheres
        return nearest_spheres, occluded_by_spheres
    return None


def surface_point(o, d, t, centers, radii):
    """Hit point projected back onto the sphere, outward unit normal (rows), offset distance.

    Reprojection (pbrt) removes the error of o + t d.  The spawn offset covers the
    float64 error of the reprojected point only: spheres are tested in float64, and a
    far-away tiny sphere must not be offset by more than its own size.
    """
    p = o + t * d
    rel = p - centers
    normal = rel / norm(rel)
    p = centers + radii * normal
    offset = 64.0 * EPS64 * (max_abs3(p) + radii)
    return p, normal, offset
