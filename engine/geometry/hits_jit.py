"""engine/geometry/scene_geometry.py's glue around the intersection kernels compiled with numba: the
sort of a batch's nearest hits into (scatter group, primitive kind) runs, and the surface points of
triangle and sphere hits.  Imported only through engine/core/backend.py's choice (it imports numba).

* `sort_hits`: `nearest_hits`' material lookup, group and key per ray, its stable argsort by key and
  the gathers of the hits' t, kind, prim, u, v and material, as one counting sort (a count per key,
  their prefix sums, then each ray written to the next place of its key, in ray order): the same
  order (a stable sort by a small integer key is unique) and the same bounds as np.searchsorted's.
* `triangle_surface`: `_triangle_surface`'s point v0 + u e1 + v e2 (the same float64 products and
  sums in the same order), normal and offset in one loop over the hits instead of nine gathers;
  `sphere_surface`: engine/geometry/shapes/spheres.py `surface_point` (the point o + t d moved
  onto the sphere along its normal, and the offset) in one loop.
* `surfaces`: the two above and quads.QuadSet.surface for all the hits of a batch in one loop (kind by
  kind as each hit's kind says), written into the batch's arrays at once instead of run by run and
  concatenated, with the normal facing the ray that PathTracer.bounce takes (`SurfaceHits.facing`).

Both give the same arrays bit for bit (tests/geometry/test_hits_jit.py)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

KINDS = 4          # scene_geometry.KINDS: TRIANGLE, SPHERE, QUAD, LIGHT (1 .. 4); NONE is 0
TRIANGLE, SPHERE, LIGHT = 1, 2, 4


@jit
def _sort_hits(t, kind, prim, u, v, primitive_material, kind_base, material_group, has_group, forced, has_forced,
               light_group, has_lights, n_keys):
    n = kind.shape[0]
    key = np.empty(n, np.int64)
    material = np.empty(n, np.int64)
    bounds = np.zeros(n_keys, np.int64)         # bounds[j]: rays with a key below j (np.searchsorted's)
    for i in range(n):
        k = np.int64(kind[i])
        m = np.int64(primitive_material[prim[i] + kind_base[k]])
        material[i] = m
        if k == 0:
            key[i] = 0
        else:
            g = np.int64(material_group[m]) if has_group else np.int64(0)
            if has_forced and forced[i] >= 0:
                g = np.int64(forced[i])
            if has_lights and k == LIGHT:
                g = light_group
            key[i] = 1 + g * KINDS + (k - 1)
        if key[i] + 1 < n_keys:
            bounds[key[i] + 1] += 1
    for j in range(1, n_keys):
        bounds[j] += bounds[j - 1]
    place = bounds[:n_keys - 1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        order[place[key[i]]] = i
        place[key[i]] += 1
    first = bounds[1]
    m_hits = n - first
    t_s = np.empty(m_hits, t.dtype)
    kind_s = np.empty(m_hits, kind.dtype)
    prim_s = np.empty(m_hits, prim.dtype)
    u_s = np.empty(m_hits, u.dtype)
    v_s = np.empty(m_hits, v.dtype)
    mat_s = np.empty(m_hits, np.int64)
    for j in range(m_hits):
        i = order[first + j]
        t_s[j], kind_s[j], prim_s[j], u_s[j], v_s[j], mat_s[j] = t[i], kind[i], prim[i], u[i], v[i], material[i]
    return order, bounds, t_s, kind_s, prim_s, u_s, v_s, mat_s


def sort_hits(t, kind, prim, u, v, primitive_material, kind_base, material_group, forced_group, light_group,
              has_lights, n_groups):
    """(order, bounds, t, kind, prim, u, v, material of the hits in order): see scene_geometry.nearest_hits,
    whose arrays these are (order: the misses, then the hits by key; bounds: the first place of each key)."""
    empty = np.zeros(1, np.int64)
    has_group = material_group is not None
    has_forced = forced_group is not None
    return _sort_hits(t, kind, prim, u, v, primitive_material, kind_base,
                      np.ascontiguousarray(material_group, np.int8) if has_group else empty.astype(np.int8),
                      has_group, np.ascontiguousarray(forced_group, np.int64) if has_forced else empty, has_forced,
                      np.int64(light_group), bool(has_lights), 2 + n_groups * KINDS)


@jit
def _max(a, b):
    """np.maximum of two scalars (NaN wins)."""
    if a != a or b != b:
        return np.nan
    return a if a >= b else b


@jit
def _triangle_surface(prim, u, v, v0, e1, e2, normal, scale, offset_scale):
    m = prim.shape[0]
    point = np.empty((3, m))
    nrm = np.empty((3, m))
    offset = np.empty(m)
    for j in range(m):
        p = prim[j]
        uj, vj = u[j], v[j]
        x = v0[0, p] + uj * e1[0, p] + vj * e2[0, p]
        y = v0[1, p] + uj * e1[1, p] + vj * e2[1, p]
        z = v0[2, p] + uj * e1[2, p] + vj * e2[2, p]
        point[0, j], point[1, j], point[2, j] = x, y, z
        nrm[0, j], nrm[1, j], nrm[2, j] = normal[0, p], normal[1, p], normal[2, p]
        offset[j] = offset_scale * _max(_max(_max(abs(x), abs(y)), abs(z)), scale[p])
    return point, nrm, offset


def triangle_surface(prim, u, v, v0, e1, e2, normal, scale, offset_scale):
    """(point, normal, offset) of triangle hits, as scene_geometry._triangle_surface."""
    return _triangle_surface(np.ascontiguousarray(prim, np.int64), np.ascontiguousarray(u, np.float64),
                             np.ascontiguousarray(v, np.float64), v0, e1, e2, normal, scale, float(offset_scale))


@jit
def _sphere_surface(o, d, t, a, prim, center, radius, eps64):
    m = prim.shape[0]
    point = np.empty((3, m))
    nrm = np.empty((3, m))
    offset = np.empty(m)
    scale = 64.0 * eps64
    for j in range(m):
        i, k = a + j, prim[j]
        r0 = (o[0, i] + t[i] * d[0, i]) - center[0, k]
        r1 = (o[1, i] + t[i] * d[1, i]) - center[1, k]
        r2 = (o[2, i] + t[i] * d[2, i]) - center[2, k]
        length = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        n0, n1, n2 = r0 / length, r1 / length, r2 / length
        r = radius[k]
        x, y, z = center[0, k] + r * n0, center[1, k] + r * n1, center[2, k] + r * n2
        point[0, j], point[1, j], point[2, j] = x, y, z
        nrm[0, j], nrm[1, j], nrm[2, j] = n0, n1, n2
        offset[j] = scale * (_max(_max(abs(x), abs(y)), abs(z)) + r)
    return point, nrm, offset


def sphere_surface(o, d, t, a, prim, center, radius, eps64):
    """spheres.surface_point of the hits a .. a + len(prim) of rows o, d and distances t (sphere prim[j]
    for hit a + j): the same operations in one loop, without the slices' copies."""
    return _sphere_surface(np.ascontiguousarray(o, np.float64), np.ascontiguousarray(d, np.float64),
                           np.ascontiguousarray(t, np.float64), int(a), np.ascontiguousarray(prim, np.int64),
                           center, radius, float(eps64))


@jit
def _surfaces(o, order, has_order, d, t, kind, prim, u, v, v0, e1, e2, tri_normal, tri_scale, tri_offset, center,
              radius, eps64, quad_normal, quad_v00, quad_scale, point, nrm, offset, facing):
    """Every hit's point, normal and offset by its kind (triangles, spheres, quads: the loops above and
    quads.QuadSet.surface, the same operations), and the normal facing the ray (PathTracer.bounce's).
    has_order: hit j's origin is o's column order[j] (o in ray order), else column j."""
    scale = 64.0 * eps64
    for j in range(kind.shape[0]):
        k, p = kind[j], prim[j]
        q = order[j] if has_order else j
        if k == TRIANGLE:
            uj, vj = u[j], v[j]
            x = v0[0, p] + uj * e1[0, p] + vj * e2[0, p]
            y = v0[1, p] + uj * e1[1, p] + vj * e2[1, p]
            z = v0[2, p] + uj * e1[2, p] + vj * e2[2, p]
            n0, n1, n2 = tri_normal[0, p], tri_normal[1, p], tri_normal[2, p]
            off = tri_offset * _max(_max(_max(abs(x), abs(y)), abs(z)), tri_scale[p])
        elif k == SPHERE:
            r0 = (o[0, q] + t[j] * d[0, j]) - center[0, p]
            r1 = (o[1, q] + t[j] * d[1, j]) - center[1, p]
            r2 = (o[2, q] + t[j] * d[2, j]) - center[2, p]
            length = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
            n0, n1, n2 = r0 / length, r1 / length, r2 / length
            r = radius[p]
            x, y, z = center[0, p] + r * n0, center[1, p] + r * n1, center[2, p] + r * n2
            off = scale * (_max(_max(abs(x), abs(y)), abs(z)) + r)
        else:                                           # QUAD (the caller sends no LIGHT hits)
            n0, n1, n2 = quad_normal[0, p], quad_normal[1, p], quad_normal[2, p]
            x, y, z = o[0, q] + t[j] * d[0, j], o[1, q] + t[j] * d[1, j], o[2, q] + t[j] * d[2, j]
            along = (x - quad_v00[0, p]) * n0 + (y - quad_v00[1, p]) * n1 + (z - quad_v00[2, p]) * n2
            x, y, z = x - along * n0, y - along * n1, z - along * n2
            off = scale * _max(_max(_max(abs(x), abs(y)), abs(z)), quad_scale[p])
        point[0, j], point[1, j], point[2, j] = x, y, z
        nrm[0, j], nrm[1, j], nrm[2, j] = n0, n1, n2
        offset[j] = off
        towards = 1.0 if d[0, j] * n0 + d[1, j] * n1 + d[2, j] * n2 < 0.0 else -1.0
        facing[0, j], facing[1, j], facing[2, j] = n0 * towards, n1 * towards, n2 * towards


def surfaces(o, d, t, kind, prim, u, v, v0, e1, e2, tri_normal, tri_scale, tri_offset, center, radius, eps64,
             quad_normal, quad_v00, quad_scale, order=None):
    """(point, normal, offset, facing) of hits on triangles, spheres and quads (no Area lights) in one loop:
    scene_geometry.surface's runs concatenated, and facing = normal * (1 if dot(d, normal) < 0 else -1).
    order: hit j's origin is o's column order[j] (None: column j)."""
    m = kind.shape[0]
    point, nrm, offset, facing = np.empty((3, m)), np.empty((3, m)), np.empty(m), np.empty((3, m))
    has_order = order is not None
    _surfaces(np.ascontiguousarray(o, np.float64),
              np.ascontiguousarray(order, np.int64) if has_order else NO_ORDER, has_order,
              np.ascontiguousarray(d, np.float64),
              np.ascontiguousarray(t, np.float64), np.ascontiguousarray(kind, np.int8),
              np.ascontiguousarray(prim, np.int64), np.ascontiguousarray(u, np.float64),
              np.ascontiguousarray(v, np.float64), v0, e1, e2, tri_normal, tri_scale, float(tri_offset),
              center, radius, float(eps64), quad_normal, quad_v00, quad_scale, point, nrm, offset, facing)
    return point, nrm, offset, facing


NO_ORDER = np.zeros(0, np.int64)


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    n = 4
    t, kind = np.array([1.0, np.inf, 2.0, 3.0]), np.array([1, 0, 2, 4], np.int8)
    prim, uv = np.array([0, -1, 0, 0], np.int64), np.zeros(n)
    pm, base = np.zeros(5, np.int64), np.array([1, 1, 2, 3, 4], np.int64)     # prim + base[kind] < 5
    for group, forced in ((None, None), (np.zeros(1, np.int8), None), (np.zeros(1, np.int8), np.full(n, -1))):
        sort_hits(t, kind, prim, uv, uv, pm, base, group, forced, 2, True, 3)
    rows = np.zeros((3, 1))
    triangle_surface(np.zeros(n, np.int64), uv, uv, rows, rows, rows, rows, np.zeros(1), 1e-6)
    sphere_surface(np.zeros((3, n)), np.ones((3, n)), np.ones(n), 1, np.zeros(2, np.int64), rows, np.ones(1), 1e-16)
    for order in (None, np.arange(n)):
        surfaces(np.zeros((3, n)), np.ones((3, n)), np.ones(n), np.array([1, 2, 3, 3], np.int8), np.zeros(n, np.int64),
                 uv, uv, rows, rows, rows, rows, np.zeros(1), 1e-6, rows, np.ones(1), 1e-16, rows, rows, np.zeros(1),
                 order)
