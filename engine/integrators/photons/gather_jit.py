"""engine/integrators/photons/gather.py compiled with numba: each query walks its cells' runs of
photons in the same order (ascending index in the sorted map), tests them with the same float
operations and adds their flux in that order, so the sums and the pairs are gather.py's bit for bit
(tests/integrators/photons/test_gather.py).  Imported only through engine/core/backend.py's choice
(it imports numba)."""
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
def _walk(q, points, facing, local, radius, segments, budget, position, normal, flux, seg, chain, offsets, lo,
          cell, dims, keys, stride, out, pair_q, pair_j, n_pairs):
    """Query q's photons in order: their flux summed into out[:, q] (out not empty), or their pairs
    written from n_pairs on (pair_q not empty), or only counted; returns the new n_pairs."""
    k = local[q]
    start, stop = offsets[k], offsets[k + 1]
    if start == stop:
        return n_pairs
    r = radius[q]
    c = cell[k]
    x, y, z = points[0, q], points[1, q], points[2, q]
    top_x, top_y, top_z = np.float64(dims[0, k] - 1), np.float64(dims[1, k] - 1), np.float64(dims[2, k] - 1)
    fx, gx = np.floor((x - r - lo[0, k]) / c), np.floor((x + r - lo[0, k]) / c)
    fy, gy = np.floor((y - r - lo[1, k]) / c), np.floor((y + r - lo[1, k]) / c)
    fz, gz = np.floor((z - r - lo[2, k]) / c), np.floor((z + r - lo[2, k]) / c)
    if gx < 0.0 or fx > top_x or gy < 0.0 or fy > top_y or gz < 0.0 or fz > top_z:
        return n_pairs
    x0, x1 = np.int64(min(max(fx, 0.0), top_x)), np.int64(min(max(gx, 0.0), top_x))
    y0, y1 = np.int64(min(max(fy, 0.0), top_y)), np.int64(min(max(gy, 0.0), top_y))
    z0, z1 = np.int64(min(max(fz, 0.0), top_z)), np.int64(min(max(gz, 0.0), top_z))
    r2 = r * r
    s0, s1, s2 = 0.0, 0.0, 0.0
    limit = segments[q]
    f0, f1, f2 = facing[0, q], facing[1, q], facing[2, q]
    b0, b1, b2 = budget[0, q], budget[1, q], budget[2, q]
    for ix in range(x0, x1 + 1):
        for iy in range(y0, y1 + 1):
            base = k * stride + (ix * dims[1, k] + iy) * dims[2, k]
            j = _lower(keys, start, stop, base + z0)
            end = _lower(keys, j, stop, base + z1 + 1)
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
def _by_slot(local, slots):
    """The queries in the order of their slots (a counting sort): one slot's photons stay in the cache
    while its queries walk them.  The order of the queries changes no sum."""
    count = np.zeros(slots + 1, np.int64)
    for q in range(local.shape[0]):
        count[local[q] + 1] += 1
    for s in range(slots):
        count[s + 1] += count[s]
    order = np.empty(local.shape[0], np.int64)
    for q in range(local.shape[0]):
        order[count[local[q]]] = q
        count[local[q]] += 1
    return order


@jit
def _flux_sums(points, facing, local, radius, segments, budget, position, normal, flux, seg, chain, offsets, lo,
               cell, dims, keys, stride):
    m = points.shape[1]
    out = np.zeros((3, m))
    none = np.zeros(0, np.int64)
    for q in _by_slot(local, offsets.shape[0] - 1):
        _walk(q, points, facing, local, radius, segments, budget, position, normal, flux, seg, chain, offsets, lo,
              cell, dims, keys, stride, out, none, none, 0)
    return out


@jit
def _pairs(points, facing, local, radius, segments, budget, position, normal, flux, seg, chain, offsets, lo,
           cell, dims, keys, stride):
    m = points.shape[1]
    empty = np.zeros((3, 0))
    none = np.zeros(0, np.int64)
    total = 0
    for q in range(m):
        total = _walk(q, points, facing, local, radius, segments, budget, position, normal, flux, seg, chain,
                      offsets, lo, cell, dims, keys, stride, empty, none, none, total)
    pair_q = np.empty(total, np.int64)
    pair_j = np.empty(total, np.int64)
    if total:
        n = 0
        for q in range(m):
            n = _walk(q, points, facing, local, radius, segments, budget, position, normal, flux, seg, chain,
                      offsets, lo, cell, dims, keys, stride, empty, pair_q, pair_j, n)
    return pair_q, pair_j


def _arguments(maps, points, facing, local, radius, segments, budget):
    m = points.shape[1]
    rows = [np.ascontiguousarray(a, np.float64) for a in (points, facing)]
    segments = np.full(m, NO_LIMIT, np.int64) if segments is None else np.ascontiguousarray(segments, np.int64)
    budget = np.full((3, m), NO_LIMIT, np.int64) if budget is None else np.ascontiguousarray(budget, np.int64)
    return (rows[0], rows[1], np.ascontiguousarray(local, np.int64), np.ascontiguousarray(radius, np.float64),
            segments, budget, maps.position, maps.normal, maps.flux, maps.segments, maps.chain, maps.offsets,
            maps.lo, maps.cell, maps.dims, maps.keys, np.int64(maps.stride))


def flux_sums(maps, points, facing, local, radius, segments=None, budget=None):
    """gather.py flux_sums (the maps' arrays are C-contiguous float64 and int64: BatchMaps makes them so)."""
    if points.shape[1] == 0 or maps.count == 0:
        return np.zeros((3, points.shape[1]))
    return _flux_sums(*_arguments(maps, points, facing, local, radius, segments, budget))


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
