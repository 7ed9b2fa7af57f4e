"""engine/integrators/photons/gather.py compiled with numba: each query walks its cells' runs of
photons in the same order (ascending index in the sorted map), tests them with the same float
operations and adds their flux in that order, so the sums and the pairs are gather.py's bit for bit
(tests/integrators/photons/test_gather.py).  Imported only through engine/core/backend.py's choice
(it imports numba).

Where gather.py searches the slot's keys for each column of a query's box, the twin reads the
column's run from the slot's column table (photon_map.py BatchMaps.columns; a slot without one is
searched as gather.py does): a row of the box's columns (x fixed, y0 .. y1) is one run too, so an
empty row is passed over after two reads, and a column's z cells are searched only when its run
has photons both in and outside them.  The same photons come out in the same order: only the
search is cheaper (docs/performance.md, branch `photons3`)."""
from __future__ import annotations

import numpy as np

from ...core.backend import numba_module
from .gather import NO_LIMIT, SAME_SIDE_COS

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)


@jit
def _lower(keys, lo, hi, value):
    """The first index in keys[lo:hi] whose key is >= value (hi: none)."""
    while lo < hi:
        mid = (lo + hi) >> 1
        if keys[mid] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo


@jit
def _run(keys, lo, hi, first, last):
    """(j, end): keys[j:end] are the keys of keys[lo:hi] within [first, last] (j == end: none); the
    ends are looked at before any search (a column's photons often all lie in the z cells asked
    for, or in none of them)."""
    if lo == hi or keys[lo] > last or keys[hi - 1] < first:
        return lo, lo
    j = lo if keys[lo] >= first else _lower(keys, lo + 1, hi, first)
    end = hi if keys[hi - 1] <= last else _lower(keys, j, hi - 1, last + 1)
    return j, end


@jit
def _walk(order, points, facing, local, radius, segments, budget, position, normal, flux, seg, chain, offsets, lo,
          cell, dims, keys, stride, columns, column_at, out, pair_q, pair_j):
    """The queries `order` walk their photons in order: each query's flux summed into out[:, q] (out
    not empty), or its pairs written one after the other (pair_q not empty), or only counted;
    returns the number of pairs.  One call walks every query (a compiled call per query, with its
    two dozen arguments, cost about 20 ns a query, as much as a query that finds nothing)."""
    n_pairs = 0
    for q in order:
        k = local[q]
        start, stop = offsets[k], offsets[k + 1]
        if start == stop:
            continue
        r = radius[q]
        c = cell[k]
        x, y, z = points[0, q], points[1, q], points[2, q]
        top_x, top_y, top_z = np.float64(dims[0, k] - 1), np.float64(dims[1, k] - 1), np.float64(dims[2, k] - 1)
        fx, gx = np.floor((x - r - lo[0, k]) / c), np.floor((x + r - lo[0, k]) / c)
        fy, gy = np.floor((y - r - lo[1, k]) / c), np.floor((y + r - lo[1, k]) / c)
        fz, gz = np.floor((z - r - lo[2, k]) / c), np.floor((z + r - lo[2, k]) / c)
        if not (gx >= 0.0 and fx <= top_x and gy >= 0.0 and fy <= top_y and gz >= 0.0 and fz <= top_z):
            continue            # gather.py cell_ranges' `meets` (False for NaN too)
        x0, x1 = np.int64(min(max(fx, 0.0), top_x)), np.int64(min(max(gx, 0.0), top_x))
        y0, y1 = np.int64(min(max(fy, 0.0), top_y)), np.int64(min(max(gy, 0.0), top_y))
        z0, z1 = np.int64(min(max(fz, 0.0), top_z)), np.int64(min(max(gz, 0.0), top_z))
        r2 = r * r
        s0, s1, s2 = 0.0, 0.0, 0.0
        limit = segments[q]
        f0, f1, f2 = facing[0, q], facing[1, q], facing[2, q]
        b0, b1, b2 = budget[0, q], budget[1, q], budget[2, q]
        table = column_at[k]
        has_table = column_at[k + 1] > table
        run_start, run_stop = start, stop
        for ix in range(x0, x1 + 1):
            row = ix * dims[1, k]
            if has_table and columns[table + row + y0] == columns[table + row + y1 + 1]:
                continue
            for iy in range(y0, y1 + 1):
                column = row + iy
                if has_table:
                    run_start, run_stop = start + columns[table + column], start + columns[table + column + 1]
                base = k * stride + column * dims[2, k]
                j, end = _run(keys, run_start, run_stop, base + z0, base + z1)
                while j < end:
                    d0 = x - position[0, j]
                    d1 = y - position[1, j]
                    d2 = z - position[2, j]
                    if (d0 * d0 + d1 * d1 + d2 * d2 <= r2
                            and f0 * normal[0, j] + f1 * normal[1, j] + f2 * normal[2, j] > SAME_SIDE_COS
                            and seg[j] <= limit and chain[0, j] <= b0 and chain[1, j] <= b1 and chain[2, j] <= b2):
                        if out.shape[1]:
                            s0 += flux[0, j]
                            s1 += flux[1, j]
                            s2 += flux[2, j]
                        elif pair_q.shape[0]:
                            pair_q[n_pairs] = q
                            pair_j[n_pairs] = j
                        n_pairs += 1
                    j += 1
        if out.shape[1]:
            out[0, q] = s0
            out[1, q] = s1
            out[2, q] = s2
    return n_pairs


@jit
def _by_slot(local, rows, slots):
    """The queries `rows` in the order of their slots (a counting sort): one slot's photons stay in
    the cache while its queries walk them.  The order of the queries changes no sum."""
    count = np.zeros(slots + 1, np.int64)
    for q in rows:
        count[local[q] + 1] += 1
    for s in range(slots):
        count[s + 1] += count[s]
    order = np.empty(rows.shape[0], np.int64)
    for q in rows:
        order[count[local[q]]] = q
        count[local[q]] += 1
    return order


@jit
def _flux_sums(points, facing, local, radius, segments, budget, position, normal, flux, seg, chain, offsets, lo,
               cell, dims, keys, stride, columns, column_at):
    out = np.zeros((3, points.shape[1]))
    none = np.zeros(0, np.int64)
    _walk(_by_slot(local, np.arange(points.shape[1]), offsets.shape[0] - 1), points, facing, local, radius, segments,
          budget, position, normal, flux, seg, chain, offsets, lo, cell, dims, keys, stride, columns, column_at, out,
          none, none)
    return out


@jit
def _lambert_radiance(rows, passes, wide, first_pass, n_passes, wide_scale, slot_radius, albedo, out, points, facing,
                      segments, budget, position, normal, flux, seg, chain, offsets, lo, cell, dims, keys, stride,
                      columns, column_at):
    """gather.py lambert_radiance: slots_of's slots and radii, the walk's sums, then out[:, q] =
    sums x albedo x (1 / (pi pi r r)) with NumPy's operations in NumPy's order."""
    m = points.shape[1]
    local = np.zeros(m, np.int64)
    radius = np.zeros(m)
    for q in rows:
        local[q] = passes[q] - first_pass + (n_passes if wide[q] else 0)
        radius[q] = slot_radius[local[q]] * (wide_scale if wide[q] else 1.0)
    sums = np.zeros((3, m))
    none = np.zeros(0, np.int64)
    _walk(_by_slot(local, rows, offsets.shape[0] - 1), points, facing, local, radius, segments, budget, position,
          normal, flux, seg, chain, offsets, lo, cell, dims, keys, stride, columns, column_at, sums, none, none)
    for q in rows:
        scale = 1.0 / (np.pi * np.pi * radius[q] * radius[q])
        out[0, q] = sums[0, q] * albedo[0, q] * scale
        out[1, q] = sums[1, q] * albedo[1, q] * scale
        out[2, q] = sums[2, q] * albedo[2, q] * scale


@jit
def _pairs(points, facing, local, radius, segments, budget, position, normal, flux, seg, chain, offsets, lo,
           cell, dims, keys, stride, columns, column_at):
    order = np.arange(points.shape[1])
    empty = np.zeros((3, 0))
    none = np.zeros(0, np.int64)
    total = _walk(order, points, facing, local, radius, segments, budget, position, normal, flux, seg, chain,
                  offsets, lo, cell, dims, keys, stride, columns, column_at, empty, none, none)
    pair_q = np.empty(total, np.int64)
    pair_j = np.empty(total, np.int64)
    if total:
        _walk(order, points, facing, local, radius, segments, budget, position, normal, flux, seg, chain, offsets,
              lo, cell, dims, keys, stride, columns, column_at, empty, pair_q, pair_j)
    return pair_q, pair_j


def _queries(points, facing, segments, budget):
    """The query arrays as the kernels take them: C-contiguous float64 rows, int64 limits (None: no limit)."""
    m = points.shape[1]
    rows = [np.ascontiguousarray(a, np.float64) for a in (points, facing)]
    segments = np.full(m, NO_LIMIT, np.int64) if segments is None else np.ascontiguousarray(segments, np.int64)
    budget = np.full((3, m), NO_LIMIT, np.int64) if budget is None else np.ascontiguousarray(budget, np.int64)
    return rows[0], rows[1], segments, budget


def _photons(maps):
    """The maps' arrays as the kernels take them (BatchMaps makes them C-contiguous float64 and int64)."""
    return (maps.position, maps.normal, maps.flux, maps.segments, maps.chain, maps.offsets, maps.lo, maps.cell,
            maps.dims, maps.keys, np.int64(maps.stride), maps.columns, maps.column_at)


def _arguments(maps, points, facing, local, radius, segments, budget):
    points, facing, segments, budget = _queries(points, facing, segments, budget)
    return (points, facing, np.ascontiguousarray(local, np.int64), np.ascontiguousarray(radius, np.float64),
            segments, budget) + _photons(maps)


def flux_sums(maps, points, facing, local, radius, segments=None, budget=None):
    """gather.py flux_sums (the maps' arrays are C-contiguous float64 and int64: BatchMaps makes them so)."""
    if points.shape[1] == 0 or maps.count == 0:
        return np.zeros((3, points.shape[1]))
    return _flux_sums(*_arguments(maps, points, facing, local, radius, segments, budget))


def lambert_radiance(maps, rows, points, facing, passes, wide, wide_scale, segments, budget, albedo, out):
    """gather.py lambert_radiance (out: C-contiguous float64)."""
    if len(rows) == 0:
        return
    _lambert_radiance(np.ascontiguousarray(rows, np.int64), np.ascontiguousarray(passes, np.int64),
                      np.ascontiguousarray(wide, np.bool_), np.int64(maps.passes[0]), np.int64(len(maps.passes)),
                      np.float64(wide_scale), maps.radius, np.ascontiguousarray(albedo, np.float64), out,
                      *_queries(points, facing, segments, budget), *_photons(maps))


def pairs(maps, points, facing, local, radius, segments=None, budget=None):
    """gather.py pairs."""
    if points.shape[1] == 0 or maps.count == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return _pairs(*_arguments(maps, points, facing, local, radius, segments, budget))


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    from .photon_map import BatchMaps
    from .tracing import Stored
    rng = np.random.default_rng(0)
    n = 16
    unit = np.tile([[0.0], [0.0], [1.0]], (1, n))
    stored = Stored(rng.random((3, n)), unit.copy(), rng.random((3, n)), unit.copy(), np.full(n, 2, np.int32),
                    np.arange(n) % 2, np.zeros((3, n), np.int16))
    maps = BatchMaps(stored, (0, 1), (0.3, 0.2), (1.0, 2.0))
    points = rng.random((3, 4))
    local = np.array([0, 1, 2, 3])
    flux_sums(maps, points, unit[:, :4], local, np.full(4, 0.3))
    pairs(maps, points, unit[:, :4], local, np.full(4, 0.3), np.full(4, 3), np.full((3, 4), 2))
    for segments, budget in ((None, None), (np.full(4, 3), np.full((3, 4), 2))):
        lambert_radiance(maps, np.arange(3), points, unit[:, :4], np.array([0, 1, 0, 1]), np.arange(4) % 2 == 0, 4.0,
                         segments, budget, rng.random((3, 4)), np.zeros((3, 4)))
