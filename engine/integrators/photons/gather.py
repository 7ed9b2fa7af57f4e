"""The gather's search and sums over a batch's photon maps (engine/integrators/photons/photon_map.py
BatchMaps), in NumPy: the reference; engine/integrators/photons/gather_jit.py is its numba twin.

Each pass's photons sit in a uniform grid of cubic cells of at least the pass's radius, sorted by
their cell's key (x dims_y + y) dims_z + z and, within a cell, by their order in the stored batch.
A query (a point, its pass, its radius) looks at the cells its box [x - r, x + r] meets, column by
column (x, then y; the z cells of a column are one run of keys), so its photons come in ascending
order of their index in the sorted map.  Every sum over a query's photons is taken in that order,
the twin's too: the same bits.  A photon is the query's when

    (dx dx + dy dy) + dz dz <= r r          (d = point - photon)
    facing . normal > SAME_SIDE_COS         (the same side of the surface)
    segments[photon] <= segments[query]     (the camera path's depth limit)
    chain[:, photon] <= budget[:, query]    (the bounce limits per type)

Keys are global over the batch (PASS_STRIDE x the pass's place in the batch + the cell's key), so one
sorted array serves every pass and one search every query.  No scipy: Blender's own Python runs it.
"""
from __future__ import annotations

import numpy as np

SAME_SIDE_COS = 0.5
NO_LIMIT = np.iinfo(np.int64).max


def cell_ranges(maps, points, local, radius):
    """Per query (rows): the first and last cell (3, M) int64 of its box in its pass's grid, and
    whether the box meets the grid (M,) bool."""
    lo = maps.lo.take(local, axis=1)
    cell = maps.cell.take(local)
    top = (maps.dims.take(local, axis=1) - 1).astype(np.float64)
    first = np.floor((points - radius - lo) / cell)
    last = np.floor((points + radius - lo) / cell)
    meets = ((last >= 0.0) & (first <= top)).all(axis=0) & (maps.offsets.take(local + 1) > maps.offsets.take(local))
    first = np.minimum(np.maximum(first, 0.0), top).astype(np.int64)
    last = np.minimum(np.maximum(last, 0.0), top).astype(np.int64)
    return first, last, meets


def pairs(maps, points, facing, local, radius, segments=None, budget=None):
    """(query, photon) of every photon of each query (rows `points`, facing normals `facing`, its
    pass `local` (M,) within the batch, its radius (M,)) under the rules of the module's docstring,
    sorted by query, then by photon (the order of the sums); segments (M,), budget (3, M): None,
    any."""
    m = points.shape[1]
    none = np.zeros(0, np.int64), np.zeros(0, np.int64)
    if m == 0 or maps.count == 0:
        return none
    first, last, meets = cell_ranges(maps, points, local, radius)
    ny = last[1] - first[1] + 1
    columns = np.where(meets, (last[0] - first[0] + 1) * ny, 0)
    total = int(columns.sum())
    if not total:
        return none
    q = np.repeat(np.arange(m), columns)
    within = np.arange(total) - np.repeat(np.cumsum(columns) - columns, columns)
    ix = first[0].take(q) + within // ny.take(q)
    iy = first[1].take(q) + within % ny.take(q)
    dims = maps.dims
    lq = local.take(q)
    base = lq * maps.stride + (ix * dims[1].take(lq) + iy) * dims[2].take(lq)
    start = np.searchsorted(maps.keys, base + first[2].take(q), "left")
    count = np.searchsorted(maps.keys, base + last[2].take(q), "right") - start
    found = int(count.sum())
    if not found:
        return none
    i = np.repeat(q, count)
    j = np.repeat(start - (np.cumsum(count) - count), count) + np.arange(found)
    d = points.take(i, axis=1) - maps.position.take(j, axis=1)
    r = radius.take(i)
    keep = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= r * r
    f, n = facing.take(i, axis=1), maps.normal.take(j, axis=1)
    keep &= f[0] * n[0] + f[1] * n[1] + f[2] * n[2] > SAME_SIDE_COS
    if segments is not None:
        keep &= maps.segments.take(j) <= segments.take(i)
    if budget is not None:
        keep &= (maps.chain.take(j, axis=1) <= budget.take(i, axis=1)).all(axis=0)
    return i[keep], j[keep]


def flux_sums(maps, points, facing, local, radius, segments=None, budget=None):
    """(3, M) the sum of each query's photons' flux (the arguments of `pairs`), in its order."""
    m = points.shape[1]
    query, photon = pairs(maps, points, facing, local, radius, segments, budget)
    out = np.zeros((3, m))
    if len(query):
        flux = maps.flux.take(photon, axis=1)
        for c in range(3):
            out[c] = np.bincount(query, flux[c], minlength=m)
    return out


def slots_of(maps, passes, wide, wide_scale):
    """(local, radius) (M,) of queries of the batch's passes `passes` (M,): each pass's slot and
    radius, or for the wide ones (M,) bool the slot of its grid of the maps' second scale and
    wide_scale x its radius (engine/integrators/photons/caustics.py builds BatchMaps with the scales
    (1, wide_scale))."""
    local = passes - maps.passes[0] + np.where(wide, len(maps.passes), 0)
    return local, maps.radius.take(local) * np.where(wide, wide_scale, 1.0)


def lambert_radiance(maps, rows, points, facing, passes, wide, wide_scale, segments, budget, albedo, out):
    """out[:, rows] = the caustic radiance at the queries `rows` (K,) of the arrays points, facing,
    albedo (3, M), passes, wide, segments (M,), budget (3, M) (segments, budget: None, any) on a
    BSDF f = albedo / pi: flux_sums x albedo / (pi^2 r^2), the operations and their order of
    photon_map.py BatchMaps.radiance; the slots and radii `slots_of`'s."""
    local, radius = slots_of(maps, passes.take(rows), wide.take(rows), wide_scale)
    at = (lambda a: None if a is None else a.take(rows, axis=-1))
    sums = flux_sums(maps, at(points), at(facing), local, radius, at(segments), at(budget))
    out[:, rows] = sums * albedo.take(rows, axis=1) * (1.0 / (np.pi * np.pi * radius * radius))
