"""Smooth shading: per-corner normals interpolated at triangle hits, and the artefacts of shading
normals handled as Cycles does.

A smooth-shaded triangle carries one normal per corner (Blender's split normals: vertex normals,
or custom normals).  At a hit with Embree's barycentrics (u, v) of vertices 1 and 2 the shading
normal is

    N_s = normalize((1 - u - v) N_0 + u N_1 + v N_2)                                   (Phong)

used for shading only: cosine terms, the BSDF sampling frame, mirror and glass directions.  The
geometric normal N_g stays for ray offsets and side tests.  Where the two disagree:

* mirror / glass: the shading normal is bent towards N_g just enough that the mirror direction
  lies above the geometric surface (Cycles' `ensure_valid_specular_reflection`,
  kernel/closure/bsdf_util.h), and a refraction that would leave on the wrong side of N_g ends;
  the microfacet lobes (Glossy, rough Glass and Refraction, the Principled glass) build their frame
  on the same bent normal (engine/materials/specular.py `specular_normal_at`), as Cycles' closure
  setup does, so a silhouette whose shading normal faces away from the viewer still scatters;
* diffuse: a direction (BSDF sample or light sample) below the geometric surface is rejected
  (weight 0), as Cycles' `bsdf_diffuse_sample` does for BSDF samples; for light samples Cycles
  gets the same through self-occlusion of closed meshes, this also holds for open ones;
* the shadow terminator (hard, faceted shadow steps on low-poly smooth spheres, where a shadow
  ray leaving the flat triangle towards a light the shading normal sees is blocked by the
  neighbouring facet): Cycles' per-object "Shadow Terminator > Geometry Offset" (default 0.1,
  exported per object) lifts the origin of grazing shadow rays of smooth triangles onto a
  parabolic surface through the corner normals (`smooth_surface_offset`, Cycles'
  `shadow_ray_smooth_surface_offset` and `shadow_ray_offset`, kernel/light/sample.h), by an
  amount that fades from 1 to 0 as the light rises above the cutoff.  Bounce rays are not
  lifted (as in Cycles).  Cycles' "Shading Offset" (default 0) is not modelled.

Bad input normals (zero length, NaN, inf) fall back to the geometric normal, with a warning
naming the object (TriangleMesh.validate_normals).
"""
from __future__ import annotations

import threading
from contextlib import contextmanager

import numpy as np

from ..core.vec import dot

# The compiled twins (engine/geometry/shading_normals_jit.py) of the render this thread traces, or
# None: NumPy.  ensure_valid_reflection is called by the BSDFs (engine/materials/specular.py) and the
# Normal Map node (engine/nodes/normals.py) with no render at hand, so PathTracer.trace sets it for
# the time of its trace (`compiled_for`); per thread, so renders of either backend may run at once.
_this_thread = threading.local()


@contextmanager
def compiled_for(numba: bool):
    """Within: this thread's ensure_valid_reflection and Normal Map node compiled (numba True), the
    same numbers, or NumPy's; the previous choice is restored after."""
    before = getattr(_this_thread, "jit", None)
    if numba:
        from . import shading_normals_jit
        _this_thread.jit = shading_normals_jit
    else:
        _this_thread.jit = None
    try:
        yield
    finally:
        _this_thread.jit = before


def compiled():
    """This thread's compiled twins (engine/geometry/shading_normals_jit.py), or None (`compiled_for`)."""
    return getattr(_this_thread, "jit", None)


def interpolate(corners: np.ndarray, u: np.ndarray, v: np.ndarray, fallback=None) -> np.ndarray:
    """Unit Phong normals (rows (3, M)) from the corner normals (M, 3, 3) of the hit triangles and
    the barycentrics u, v of corners 1 and 2.  A hit exactly at a corner returns its normal.  Where
    the corners cancel (opposite normals: a zero sum) the `fallback` rows (the geometric normal)."""
    w0 = 1.0 - u - v
    n = (w0[:, None] * corners[:, 0] + u[:, None] * corners[:, 1] + v[:, None] * corners[:, 2]).T
    return _unit_or(n, fallback)


def interpolate_rows(rows: np.ndarray, u: np.ndarray, v: np.ndarray, fallback=None) -> np.ndarray:
    """interpolate with the corner normals as rows (9, M) (corner c's component x in row 3 c + x):
    the same numbers, from contiguous rows."""
    w0 = 1.0 - u - v
    n = w0 * rows[0:3]
    n += u * rows[3:6]
    n += v * rows[6:9]
    return _unit_or(n, fallback)


def _unit_or(n, fallback):
    length = np.sqrt(dot(n, n))
    n = n / np.maximum(length, 1e-300)
    if fallback is not None:
        n = np.where(length > 1e-9, n, fallback)
    return n


class SmoothNormals:
    """Corner normals of every smooth triangle of a scene, indexed by the geometry's triangle
    number (the meshes concatenated in scene order, as engine/geometry/scene_geometry.py builds them)."""

    def __init__(self, meshes):
        index, corners, cutoff, start = [], [], [], 0
        for mesh in meshes:
            t = len(mesh.triangles)
            if not t:
                continue
            idx = np.full(t, -1, dtype=np.int64)
            if mesh.normals is not None:
                smooth = np.ones(t, bool) if mesh.smooth is None else np.asarray(mesh.smooth, bool)
                rows_ = np.flatnonzero(smooth)
                idx[rows_] = start + np.arange(len(rows_))
                corners.append(np.asarray(mesh.normals, dtype=np.float64)[rows_])
                cutoff.append(np.full(len(rows_), float(mesh.terminator_offset)))
                start += len(rows_)
            index.append(idx)
        self.index = np.concatenate(index) if index else np.zeros(0, np.int64)
        self.corners = np.concatenate(corners) if corners else np.zeros((0, 3, 3))
        self.cutoff = np.concatenate(cutoff) if cutoff else np.zeros(0)    # geometry offset per smooth triangle
        self.count = start
        self.jit = None         # the compiled twins (engine/geometry/shading_normals_jit.py), set by SceneGeometry

    def terminator_lift(self, prim, u, v, facing, triangles):
        """(lift rows (3, M), cutoff (M,)) for shadow rays from triangle hits (prim, u, v) with
        geometric normals `facing` (towards the viewer); zero where flat or with cutoff 0.
        triangles: (T, 3, 3) vertices of the geometry."""
        m = len(prim)
        lift, cutoff = np.zeros((3, m)), np.zeros(m)
        row = self.index.take(prim)
        sel = np.flatnonzero(row >= 0)
        if len(sel):
            r = row.take(sel)
            cut = self.cutoff.take(r)
            on = np.flatnonzero(cut > 0.0)
            if len(on):
                i, r = sel.take(on), r.take(on)
                lift[:, i] = smooth_surface_offset(triangles.take(prim.take(i), axis=0), self.corners.take(r, axis=0),
                                                   u.take(i), v.take(i), facing[:, i])
                cutoff[i] = cut.take(on)
        return lift, cutoff

    def rows(self) -> np.ndarray:
        """The corner normals as rows (9, count) (made on first use)."""
        if getattr(self, "_rows", None) is None:
            self._rows = np.ascontiguousarray(self.corners.reshape(-1, 9).T)
        return self._rows

    def shading(self, prim, u, v, geometric: np.ndarray) -> np.ndarray:
        """Shading normals (rows) of triangle hits: interpolated on smooth triangles, the
        geometric normal (a copy of its columns) on flat ones."""
        if self.jit is not None:            # the same numbers in one loop
            return self.jit.shading(prim, u, v, geometric, self.index, self.corners)
        out = np.array(geometric, dtype=np.float64, copy=True)
        row = self.index.take(prim)
        smooth = np.flatnonzero(row >= 0)
        if len(smooth):
            out[:, smooth] = interpolate_rows(self.rows().take(row.take(smooth), axis=1), u.take(smooth),
                                              v.take(smooth), out[:, smooth])
        return out


def tangent_plane_bound(p, corners, normals, sign: float) -> np.ndarray:
    """The smallest over the corners i of max(sign n_i.(v_i - p) + e_i, 0), e_i = max(0, sign
    n_i.(v_j - v_i) over the other corners j): how far the corners' tangent planes (normals times
    `sign`) let the lift go (Cycles' shadow_ray_smooth_surface_offset)."""
    return _plane_bounds(p, corners, normals, (sign,))[0]


def _plane_bounds(p, corners, normals, signs) -> list:
    """tangent_plane_bound for each sign of `signs` (+1.0 and / or -1.0), the dot products made once:
    sign * d is d or -d exactly, so each bound has the numbers it has alone."""
    bounds = [None] * len(signs)
    for i, (vi, ni) in enumerate(zip(corners, normals)):
        edges = [dot(vj - vi, ni) for j, vj in enumerate(corners) if j != i]
        to_p = dot(vi - p, ni)
        for k, sign in enumerate(signs):
            edge = 0.0
            for d in edges:
                edge = np.maximum(edge, sign * d)
            gi = np.maximum(sign * to_p + edge, 0.0)
            bounds[k] = gi if bounds[k] is None else np.minimum(bounds[k], gi)
    return bounds


def smooth_surface_offset(V, N, u, v, ng) -> np.ndarray:
    """Cycles' shadow_ray_smooth_surface_offset, vectorised: the lift (rows (3, M)) from the flat
    triangle at barycentrics (u, v) of corners 1 and 2 to a parabolic approximation of the smooth
    surface through the corner normals, bounded by the corners' tangent planes (a local linear
    envelope).  V, N: (M, 3, 3) corner positions and unit corner normals; ng: geometric normals
    (rows) on the side the shadow ray leaves from."""
    w0, w1, w2 = 1.0 - u - v, u, v                          # weights of corners 0, 1, 2
    rows_v = np.ascontiguousarray(np.asarray(V).reshape(-1, 9).T)     # rows: contiguous components
    rows_n = np.ascontiguousarray(np.asarray(N).reshape(-1, 9).T)
    v0, v1, v2 = rows_v[0:3], rows_v[3:6], rows_v[6:9]
    n0, n1, n2 = rows_n[0:3], rows_n[3:6], rows_n[6:9]
    p = v0 * w0 + v1 * w1 + v2 * w2
    n = n0 * w0 + n1 * w1 + n2 * w2                          # not normalised (as Cycles)
    a = dot(n2 - n0, v0 - v2)
    b = dot(n2 - n1, v1 - v2)
    c = dot(n1 - n0, v1 - v0)
    h = a * w0 * (w0 - 1.0) + (a + b + c) * w0 * w1 + b * w1 * (w1 - 1.0)   # parabolic approximation
    front = dot(n, ng) > 0.0
    # Front: the corners' tangent planes bound the lift from above (local linear envelope); back:
    # the same with the normals flipped against the side the ray leaves from.
    above, below = _plane_bounds(p, (v0, v1, v2), (n0, n1, n2), (1.0, -1.0))
    h_front = np.maximum(above, h * 0.5)
    h_back = np.minimum(-below, h * 0.5)
    return n * np.where(front, h_front, h_back)


def terminator_amount(nl, ngl, cutoff) -> np.ndarray:
    """How much of the lift a shadow ray gets (Cycles' shadow_ray_offset): nl = N_s . L and
    ngl = N_g . L (both on the side the ray leaves from), cutoff = the object's geometry offset;
    1 for grazing light, fading to 0 once N_g . L exceeds the cutoff."""
    with np.errstate(divide="ignore", invalid="ignore"):
        amount = np.where(nl < cutoff, np.clip(2.0 - (ngl + nl) / cutoff, 0.0, 1.0),
                          np.clip(1.0 - ngl / cutoff, 0.0, 1.0))
    return np.where(cutoff > 0.0, amount, 0.0)


def has_smooth(meshes) -> int:
    """How many smooth-shaded triangles the meshes have."""
    total = 0
    for mesh in meshes:
        if mesh.normals is not None and len(mesh.triangles):
            total += len(mesh.triangles) if mesh.smooth is None else int(np.count_nonzero(mesh.smooth))
    return total


def ensure_valid_reflection(ng: np.ndarray, i: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Cycles' ensure_valid_specular_reflection (kernel/closure/bsdf_util.h), vectorised.

    ng: geometric normal, i: direction towards the viewer (-ray), n: shading normal, all unit
    rows on the viewer's side of ng (dot(i, ng) >= 0).  Returns n where its mirror direction
    R = 2 (n.i) n - i is at least min(0.9 i.ng, 0.01) above the geometric surface, else the
    normal n' in the plane of n and ng, tilted towards ng, whose reflection lies exactly at that
    height (the larger root of 2 (n'.i) n'_z - i_z = t), or ng when no such normal exists.
    Compiled within compiled_for(True): the same numbers in one loop."""
    jit = compiled()
    if jit is not None:
        return jit.ensure_valid_reflection(ng, i, n)
    iz = dot(i, ng)
    r = 2.0 * dot(n, i) * n - i
    threshold = np.minimum(0.9 * iz, 0.01)
    bad = np.flatnonzero(dot(ng, r) < threshold)
    if not len(bad):
        return n
    out = np.array(n, copy=True)
    ng_b, i_b, n_b, t, iz_b = ng[:, bad], i[:, bad], n[:, bad], threshold[bad], iz[bad]
    x = n_b - dot(n_b, ng_b) * ng_b                         # X axis: n's part orthogonal to ng
    x_len = np.sqrt(dot(x, x))
    x = np.where(x_len > 1e-12, x / np.maximum(x_len, 1e-300), n_b)
    ix = dot(i_b, x)
    a = ix * ix + iz_b * iz_b
    b = np.sqrt(np.maximum(ix * ix * (a - t * t), 0.0))
    c = iz_b * t + a
    with np.errstate(divide="ignore", invalid="ignore"):
        fac = 0.5 / a
    n1z2, n2z2 = fac * (b + c), fac * (c - b)
    valid1 = (n1z2 > 1e-5) & (n1z2 <= 1.0 + 1e-5)
    valid2 = (n2z2 > 1e-5) & (n2z2 <= 1.0 + 1e-5)
    n1 = (np.sqrt(np.maximum(1.0 - n1z2, 0.0)), np.sqrt(np.maximum(n1z2, 0.0)))
    n2 = (np.sqrt(np.maximum(1.0 - n2z2, 0.0)), np.sqrt(np.maximum(n2z2, 0.0)))
    r1 = 2.0 * (n1[0] * ix + n1[1] * iz_b) * n1[1] - iz_b
    r2 = 2.0 * (n2[0] * ix + n2[1] * iz_b) * n2[1] - iz_b
    both = valid1 & valid2
    ok1, ok2 = r1 >= 1e-5, r2 >= 1e-5
    # Both roots possible: the valid reflection, the shallower one if both are (closest to n).
    pick1_both = np.where(ok1 & ok2, r1 < r2, r1 > r2)
    pick1 = np.where(both, pick1_both, valid1)
    nx = np.where(pick1, n1[0], n2[0])
    nz = np.where(pick1, n1[1], n2[1])
    new = nx * x + nz * ng_b
    new = np.where(valid1 | valid2, new, ng_b)
    new = np.where(np.isfinite(new).all(axis=0), new, ng_b)
    out[:, bad] = new / np.maximum(np.sqrt(dot(new, new)), 1e-300)
    return out
