"""The caustic photons of a batch of passes and the density estimate over them (Jensen 1996, eq. of
the photon map's radiance estimate):

    L_c(x, wo) = 1 / (pi r^2)  sum over photons p within r of x  f(x, wo, wi_p) Phi_p

with a disk kernel of the pass's radius r, over the photons whose surface faces the same way
(facing normals within 60 degrees: photons on the other side of a thin wall, or on a
perpendicular wall within r, are not gathered).  `BatchMaps` holds the stored photons of a batch
of passes, each pass's in a uniform grid of cells of at least its radius; the search and the sums
are engine/integrators/photons/gather.py's (NumPy) or gather_jit.py's (numba, the same bits), for
every pass of the batch in one call.  No scipy needed (Blender's own Python runs it).

The radius schedule: r_k^2 = r_1^2 prod_{i=1}^{k-1} (i + alpha) / (i + 1) for pass k = 1, 2, ...
(SPPM's reduction, Hachisuka & Jensen 2009, as a global per-pass radius: probabilistic
progressive photon mapping, Knaus & Zwicker 2011).  Each pass is an independent estimate whose
bias falls as r_k^2 ~ k^(alpha - 1) and whose variance grows as 1 / r_k^2; the image is the mean
over the passes, whose bias falls as n^(alpha - 1) and variance as n^(-alpha): consistent for
0 < alpha < 1.
"""
from __future__ import annotations

import math

import numpy as np

from ...core.vec import dot

from . import gather
from .gather import SAME_SIDE_COS  # noqa: F401  (the rule's constant, where it was)

try:
    from scipy.special import gammaln
except ImportError:             # Blender's Python: the standard library's log Gamma
    gammaln = math.lgamma

GRID_CELLS = 1 << 16            # a pass's grid has at most this many cells per axis (+ 1) ...
PASS_STRIDE = 1 << 50           # ... so its keys are below 2^49, and a batch's keys stride * pass + key
MAX_PASSES = 1 << 12            # passes of one BatchMaps at most (its keys below 2^62)
COLUMNS_PER_PHOTON = 32         # a slot's column table (BatchMaps.columns) has at most this many entries
MIN_COLUMNS = 1 << 16           # per photon of the slot, or this many: past that the kernel searches the keys


def radius_of_pass(r1: float, k: int, alpha: float) -> float:
    """r_k (k = 0, 1, ...: the first pass has r1), the product in closed form with Gamma functions."""
    j = k + 1
    log_ratio = gammaln(j + alpha) - gammaln(1.0 + alpha) - gammaln(j + 1.0)
    return float(r1 * np.exp(0.5 * log_ratio))




def pass_grid(position: np.ndarray, radius: float):
    """(lo (3,), cell, dims (3,) int64, keys (N,) int64) of a uniform grid over the photons at
    `position` (3, N): cubic cells of at least `radius` (and of 1 / GRID_CELLS of the photons' extent)
    from their lowest corner, a photon's key (x dims_y + y) dims_z + z of its cell."""
    if position.shape[1] == 0:
        return np.zeros(3), max(float(radius), 1e-300), np.ones(3, np.int64), np.zeros(0, np.int64)
    lo = position.min(axis=1)
    span = position.max(axis=1) - lo
    cell = max(float(radius), float(span.max()) / GRID_CELLS, 1e-300)
    dims = np.floor(span / cell).astype(np.int64) + 1
    c = np.minimum(np.floor((position - lo[:, None]) / cell).astype(np.int64), (dims - 1)[:, None])
    return lo, cell, dims, (c[0] * dims[1] + c[1]) * dims[2] + c[2]


def column_table(key: np.ndarray, dims: np.ndarray) -> np.ndarray:
    """(dims_x dims_y + 1,) int32: where each column of a grid of `dims` starts among the photons
    with cell keys `key` (N,, in any order: a count per column) once they are sorted by key
    (BatchMaps.columns); empty when the grid has more columns than COLUMNS_PER_PHOTON N or
    MIN_COLUMNS."""
    n_columns = int(dims[0]) * int(dims[1])
    if n_columns > max(COLUMNS_PER_PHOTON * len(key), MIN_COLUMNS):
        return np.zeros(0, np.int32)
    if len(key) >= np.iinfo(np.int32).max:
        raise ValueError(f"{len(key)} photons in one pass: at most {np.iinfo(np.int32).max - 1}")
    count = np.bincount(key // dims[2], minlength=n_columns)
    return np.concatenate([[0], np.cumsum(count)]).astype(np.int32)


class BatchMaps:
    """The photon maps of the passes `passes` (labels of the stored photons), with radii `radii`,
    each in one grid per scale of `scales` (cells of at least scale x the pass's radius: a query
    over that scale x the radius looks at a few cells): a slot per (scale, pass), slot
    s = scale's place x len(passes) + pass's place.  A slot holds its pass's stored photons, sorted
    by their cell's key in its grid (stable: within a cell in their stored order); the slots come
    one after the other, `offsets` (slots + 1,) bound them.

    `columns` (int32, relative to the slot's offset) tells where each column of a slot's grid
    starts: slot s's table is columns[column_at[s]:column_at[s + 1]], dims_x dims_y + 1 entries,
    entry x dims_y + y the place of the column's first photon (its keys (x dims_y + y) dims_z + z
    for every z are one run), the last the slot's count.  The compiled walk (gather_jit.py) reads a
    column's run there instead of searching the slot's keys for it; a slot whose grid has more
    columns than COLUMNS_PER_PHOTON per photon (or MIN_COLUMNS) has no table (an empty range) and
    is searched.  Which photons are read, and in which order, is the same either way."""

    def __init__(self, stored, passes, radii, scales=(1.0,)):
        """stored: engine/integrators/photons/tracing.py Stored."""
        passes = tuple(int(j) for j in passes)
        self.passes, self.scales, self.stride = passes, tuple(float(x) for x in scales), PASS_STRIDE
        p = len(passes)
        slots = p * len(self.scales)
        if slots > MAX_PASSES:
            raise ValueError(f"{slots} grids in one BatchMaps: at most {MAX_PASSES}")
        self.radius = np.tile(np.array([float(r) for r in radii]), len(self.scales))     # per slot: its pass's
        self.lo, self.cell, self.dims = np.zeros((3, slots)), np.zeros(slots), np.zeros((3, slots), np.int64)
        order, keys, tables = [], [], []
        mine = [np.flatnonzero(stored.label == j) for j in passes]
        for s in range(slots):
            k = s % p
            lo, cell, dims, key = pass_grid(stored.position.take(mine[k], axis=1),
                                            self.radius[s] * self.scales[s // p])
            self.lo[:, s], self.cell[s], self.dims[:, s] = lo, cell, dims
            sort = np.argsort(key, kind="stable")
            order.append(mine[k].take(sort))
            keys.append(s * PASS_STRIDE + key.take(sort))
            tables.append(column_table(key, dims))
        order = np.concatenate(order) if order else np.zeros(0, np.int64)
        self.source = order                 # each photon's index in the stored batch
        self.keys = np.ascontiguousarray(np.concatenate(keys) if keys else np.zeros(0, np.int64), np.int64)
        self.offsets = np.concatenate([[0], np.cumsum([len(o) for o in keys])]).astype(np.int64)
        self.columns = np.concatenate(tables) if tables else np.zeros(0, np.int32)
        self.column_at = np.concatenate([[0], np.cumsum([len(t) for t in tables])]).astype(np.int64)
        self.position, self.incoming, self.flux, self.normal = (
            np.ascontiguousarray(a.take(order, axis=1), np.float64)
            for a in (stored.position, stored.incoming, stored.flux, stored.normal))
        self.segments = np.ascontiguousarray(stored.segments.take(order), np.int64)
        chain = stored.chain if stored.chain is not None else np.zeros((3, len(stored.label)), np.int16)
        self.chain = np.ascontiguousarray(chain.take(order, axis=1), np.int64)
        self.count = len(order)
        self.nbytes = sum(a.nbytes for a in (self.position, self.incoming, self.flux, self.normal, self.segments,
                                             self.chain, self.keys, self.source, self.columns))

    def slot(self, k: int, scale: float = 1.0) -> int:
        """The slot of pass k whose grid is scale's (the grid of the largest scale up to it)."""
        fits = [i for i, x in enumerate(self.scales) if x <= scale] or [0]
        return max(fits, key=lambda i: self.scales[i]) * len(self.passes) + self.passes.index(int(k))

    def radiance(self, bsdf, si, points, facing, local, radius, segments=None, budget=None, kernels=gather):
        """(3, M) the caustic radiance towards si.wo at the M points (rows) of the ShadingPoint si
        (engine/materials/protocol.py) whose BSDF is `bsdf`; facing: their geometric normals on the
        viewer's side; local (M,): each point's slot (its pass and grid: `slot`); radius (M,): its
        radius (vertices seen after a diffuse bounce gather over a wider disk); segments (M,): the
        most segments a photon's path may have at each point (the camera path's depth limit; None:
        any); budget (3, M): the most glossy, transmission and transparent bounces a photon's chain
        may make but its first (Cycles' bounce limits per type left over by the camera path,
        engine/integrators/light_paths.py; None: any); kernels: gather.py or gather_jit.py."""
        m = points.shape[1]
        albedo = bsdf.lambert_albedo(si)
        if albedo is not None:              # f = rho / pi for every direction: sum the flux per point first
            out = kernels.flux_sums(self, points, facing, local, radius, segments, budget)
            return out * albedo * (1.0 / (np.pi * np.pi * radius * radius))
        out = np.zeros((3, m))
        query, photon = kernels.pairs(self, points, facing, local, radius, segments, budget)
        if not len(query):
            return out
        at = si.take(query)
        wi = self.incoming.take(photon, axis=1)
        f_cos, _ = bsdf.eval(at, wi)
        cos = np.abs(dot(at.n, wi))
        f = np.where(cos > 1e-6, f_cos / np.maximum(cos, 1e-6), 0.0)
        contrib = f * self.flux.take(photon, axis=1)
        for c in range(3):
            out[c] = np.bincount(query, contrib[c], minlength=m)
        return out * (1.0 / (np.pi * radius * radius))


class PhotonMap:
    """One pass of a BatchMaps: its photons (views) and its density estimate."""

    def __init__(self, maps: BatchMaps, k: int):
        self.maps, self.k = maps, int(k)
        first = maps.slot(k)
        span = slice(int(maps.offsets[first]), int(maps.offsets[first + 1]))
        self.position, self.incoming, self.flux, self.normal = (
            a[:, span] for a in (maps.position, maps.incoming, maps.flux, maps.normal))
        self.count = span.stop - span.start
        self.radius = float(maps.radius[first])

    def radiance(self, bsdf, si, points, facing, segments=None, scale: float = 1.0, budget=None,
                 kernels=gather) -> np.ndarray:
        """BatchMaps.radiance at points all of this pass, over `scale` x its radius."""
        m = points.shape[1]
        return self.maps.radiance(bsdf, si, points, facing, np.full(m, self.maps.slot(self.k, scale), np.int64),
                                  np.full(m, self.radius * scale), segments, budget, kernels)
