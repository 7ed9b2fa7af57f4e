"""Voronoi Texture (ShaderNodeTexVoronoi) as Cycles computes it (intern/cycles/kernel/svm/voronoi.h).

Features F1, F2, SMOOTH_F1, DISTANCE_TO_EDGE, N_SPHERE_RADIUS; metrics EUCLIDEAN, MANHATTAN,
CHEBYCHEV, MINKOWSKI (2-D to 4-D; 1-D is always |a - b|); 1-D to 4-D; Blender 4.0+'s fractal
Voronoi (Detail, Roughness, Lacunarity, the `normalize` property).  Props: "voronoi_dimensions",
"feature", "distance", "normalize".

The loops over neighbouring cells run in Cycles' order (x innermost) with the same strict `<`
comparisons, one NumPy pass per neighbour over all points, so ties resolve as in Cycles.
Versions (ctx.cycles_version): Blender 5.0 hashes 2-D to 4-D integer cells with PCG
(engine/nodes/procedural/hash.py), 3.x-4.5 hash the float cell positions with lookup3; 3.x has no
fractal inputs (one octave), and its F1 compares true distances, not 5.0's squared bound.
"""
from __future__ import annotations

import itertools

import numpy as np

from .common import (choice, dims_of, out_float, out_rows, points, scalar, vector,
                                            version_of)
from .hash import (hash_float2_to_float2, hash_float2_to_float3,
                                          hash_float3_to_float3, hash_float4_to_float3,
                                          hash_float4_to_float4, hash_float_n_to_float,
                                          hash_float_to_float3, hash_int_n_to_float3,
                                          hash_int_n_to_float_n)
from .perlin import F32, mix

FEATURES = ("F1", "F2", "SMOOTH_F1", "DISTANCE_TO_EDGE", "N_SPHERE_RADIUS")
METRICS = ("EUCLIDEAN", "MANHATTAN", "CHEBYCHEV", "MINKOWSKI")
FLT_MAX = F32(np.finfo(np.float32).max)
PCG_SINCE = (5, 0)
FRACTAL_SINCE = (4, 0)


class Grid:
    """The lattice cells of a batch: float floors `fl`, their ints for PCG, and, where many points
    share a cell, one representative point per distinct cell (`rep`) and each point's cell
    (`inv`), so that a neighbour's hash is computed once per distinct cell and gathered."""

    SHARED = 4          # dedupe when the batch has at least this many points per distinct cell
    MIN_POINTS = 1024

    def __init__(self, fl, ints):
        self.fl, self.ints, self.rep, self.inv = fl, ints, None, None
        n = fl[0].size
        if n < self.MIN_POINTS:
            return
        keys = [f.astype(np.int64) for f in fl] if ints is None else list(ints)
        lows = [int(k.min()) for k in keys]
        spans = [int(k.max()) - lo + 1 for k, lo in zip(keys, lows)]
        if float(np.prod([float(x) for x in spans])) >= 2.0 ** 62:
            return
        key = np.zeros(n, dtype=np.int64)
        for k, lo, span in zip(keys, lows, spans):
            key = key * span + (k - lo)
        uniq, rep, inv = np.unique(key, return_index=True, return_inverse=True)
        if uniq.size * self.SHARED <= n:
            self.rep, self.inv = rep, inv.reshape(-1)

    def hashed(self, fn, off):
        """fn(cells + off) per point (a tuple of arrays), via the distinct cells where it pays."""
        per_point = any(np.ndim(o) for o in off)
        if self.rep is None or per_point:
            return fn(self.fl, self.ints, off)
        fl = tuple(f[self.rep] for f in self.fl)
        ints = None if self.ints is None else tuple(i[self.rep] for i in self.ints)
        return tuple(v[self.inv] for v in fn(fl, ints, off))


class Cells:
    """The point and colour hashes of lattice cells of one Blender version, and the metric."""

    def __init__(self, dims, version, metric, exponent):
        self.dims, self.metric, self.exponent = dims, metric, exponent
        self.pcg = dims >= 2 and tuple(version) >= PCG_SINCE
        self.legacy = tuple(version) < FRACTAL_SINCE

    def cell(self, coord):
        """The batch's cells (a Grid) and each point's local position in its cell."""
        fl = tuple(np.floor(c) for c in coord)
        local = tuple(c - f for c, f in zip(coord, fl))
        ints = tuple(f.astype(np.int64) for f in fl) if self.pcg else None
        return Grid(fl, ints), local

    def point(self, grid, off):
        """Hash of cell `cell + off` into a point offset in [0, 1]^D."""
        return grid.hashed(self._point, off)

    def color(self, grid, off):
        return grid.hashed(self._color, off)

    def _point(self, fl, ints, off):
        if self.pcg:
            return hash_int_n_to_float_n(*(i + o for i, o in zip(ints, off)))
        k = tuple(f + F32(o) for f, o in zip(fl, off))
        if self.dims == 1:
            return (hash_float_n_to_float(k[0]),)
        return {2: hash_float2_to_float2, 3: hash_float3_to_float3, 4: hash_float4_to_float4}[self.dims](*k)

    def _color(self, fl, ints, off):
        if self.pcg:
            return hash_int_n_to_float3(*(i + o for i, o in zip(ints, off)))
        k = tuple(f + F32(o) for f, o in zip(fl, off))
        return {1: hash_float_to_float3, 2: hash_float2_to_float3, 3: hash_float3_to_float3,
                4: hash_float4_to_float3}[self.dims](*k)

    def distance(self, a, b):
        """`voronoi_distance` (1-D: |b - a| whatever the metric)."""
        d = [np.abs(x - y) for x, y in zip(a, b)]
        if self.dims == 1:
            return d[0]
        if self.metric == "EUCLIDEAN":
            return np.sqrt(_sum(x * x for x in d))
        if self.metric == "MANHATTAN":
            return _sum(d)
        if self.metric == "CHEBYCHEV":
            return _max(d)
        if self.metric == "MINKOWSKI":
            e = self.exponent
            return np.power(_sum(np.power(x, e) for x in d), F32(1.0) / e)
        raise AssertionError(self.metric)

    def bound(self, a, b):
        """`voronoi_distance_bound`: orders like the distance, cheaper (5.0's F1)."""
        if self.legacy or self.dims == 1:
            return self.distance(a, b)
        d = [np.abs(x - y) for x, y in zip(a, b)]
        if self.metric == "EUCLIDEAN":
            return _sum(x * x for x in d)
        if self.metric == "MINKOWSKI":
            return _sum(np.power(x, self.exponent) for x in d)
        return self.distance(a, b)


def _sum(xs):
    xs = list(xs)
    s = xs[0]
    for x in xs[1:]:
        s = s + x
    return s


def _max(xs):
    xs = list(xs)
    s = xs[0]
    for x in xs[1:]:
        s = np.maximum(s, x)
    return s


def _offsets(dims, reach):
    """Neighbour offsets in Cycles' loop order: x innermost."""
    for t in itertools.product(range(-reach, reach + 1), repeat=dims):
        yield t[::-1]


def _sel(m, a, b):
    return tuple(np.where(m, x, y) for x, y in zip(a, b))


def _point_pos(cells, grid, off, randomness):
    h = cells.point(grid, off)
    return tuple(F32(o) + hv * randomness for o, hv in zip(off, h))


def f1(cells, coord, randomness, params=None):
    grid, local = cells.cell(coord)
    fl = grid.fl
    n = coord[0].shape
    best = np.full(n, F32(8.0) if cells.legacy else FLT_MAX, dtype=F32)
    target_off = tuple(np.zeros(n, dtype=np.int64) for _ in coord)
    target = tuple(np.zeros(n, dtype=F32) for _ in coord)
    for off in _offsets(cells.dims, 1):
        pp = _point_pos(cells, grid, off, randomness)
        d = cells.bound(pp, local)
        m = d < best
        best = np.where(m, d, best)
        target_off = tuple(np.where(m, o, t) for o, t in zip(off, target_off))
        target = _sel(m, pp, target)
    dist = best if (cells.legacy or cells.dims == 1) else cells.distance(target, local)
    color = cells.color(grid, target_off)
    return dist, color, tuple(t + f for t, f in zip(target, fl))


def smooth_f1(cells, coord, randomness, smoothness):
    grid, local = cells.cell(coord)
    fl = grid.fl
    n = coord[0].shape
    sdist = np.zeros(n, dtype=F32)
    spos = tuple(np.zeros(n, dtype=F32) for _ in coord)
    scol = tuple(np.zeros(n, dtype=F32) for _ in range(3))
    first = True
    for off in _offsets(cells.dims, 2):
        pp = _point_pos(cells, grid, off, randomness)
        d = cells.distance(pp, local)
        if first:
            h = np.ones(n, dtype=F32)
            first = False
        else:
            h = _smoothstep(F32(0.5) + F32(0.5) * (sdist - d) / smoothness)
        corr = smoothness * h * (F32(1.0) - h)
        sdist = mix(sdist, d, h) - corr
        corr = corr / (F32(1.0) + F32(3.0) * smoothness)
        col = cells.color(grid, off)
        scol = tuple(mix(s, c, h) - corr for s, c in zip(scol, col))
        spos = tuple(mix(s, p, h) - corr for s, p in zip(spos, pp))
    return sdist, scol, tuple(f + s for f, s in zip(fl, spos))


def _smoothstep(x):
    """smoothstep(0, 1, x) of Cycles."""
    t = np.clip(x, F32(0.0), F32(1.0))
    r = (F32(3.0) - F32(2.0) * t) * (t * t)
    return np.where(x < 0, F32(0.0), np.where(x >= 1, F32(1.0), r)).astype(F32)


def f2(cells, coord, randomness, params=None):
    grid, local = cells.cell(coord)
    fl = grid.fl
    n = coord[0].shape
    init = F32(8.0) if cells.legacy else FLT_MAX
    d1, d2 = np.full(n, init, dtype=F32), np.full(n, init, dtype=F32)
    zeros_i = tuple(np.zeros(n, dtype=np.int64) for _ in coord)
    zeros_f = tuple(np.zeros(n, dtype=F32) for _ in coord)
    o1, o2, p1, p2 = zeros_i, zeros_i, zeros_f, zeros_f
    for off in _offsets(cells.dims, 1):
        pp = _point_pos(cells, grid, off, randomness)
        d = cells.distance(pp, local)
        offs = tuple(np.full(n, o, dtype=np.int64) for o in off)
        m1 = d < d1
        m2 = ~m1 & (d < d2)
        d2 = np.where(m1, d1, np.where(m2, d, d2))
        o2 = _sel(m1, o1, _sel(m2, offs, o2))
        p2 = _sel(m1, p1, _sel(m2, pp, p2))
        d1 = np.where(m1, d, d1)
        o1 = _sel(m1, offs, o1)
        p1 = _sel(m1, pp, p1)
    return d2, cells.color(grid, o2), tuple(p + f for p, f in zip(p2, fl))


def distance_to_edge(cells, coord, randomness):
    grid, local = cells.cell(coord)
    n = coord[0].shape
    if cells.dims == 1:
        h = lambda o: cells.point(grid, (o,))[0]  # noqa: E731
        mid = h(0) * randomness
        left = F32(-1.0) + h(-1) * randomness
        right = F32(1.0) + h(1) * randomness
        a = np.abs((mid + left) / F32(2.0) - local[0])
        b = np.abs((mid + right) / F32(2.0) - local[0])
        return np.minimum(a, b)
    vectors = []
    best = np.full(n, FLT_MAX, dtype=F32)
    closest = tuple(np.zeros(n, dtype=F32) for _ in coord)
    for off in _offsets(cells.dims, 1):
        v = tuple(p - q for p, q in zip(_point_pos(cells, grid, off, randomness), local))
        vectors.append(v)
        d = _sum(x * x for x in v)
        m = d < best
        best = np.where(m, d, best)
        closest = _sel(m, v, closest)
    best = np.full(n, FLT_MAX, dtype=F32)
    for v in vectors:
        perp = tuple(a - b for a, b in zip(v, closest))
        pp = _sum(x * x for x in perp)
        ok = pp > F32(0.0001)
        length = np.sqrt(pp)
        with np.errstate(divide="ignore", invalid="ignore"):
            de = _sum(((c + a) / F32(2.0)) * (p / length) for c, a, p in zip(closest, v, perp))
        best = np.where(ok, np.minimum(best, de), best)
    return best


def n_sphere_radius(cells, coord, randomness):
    grid, local = cells.cell(coord)
    n = coord[0].shape
    dims = cells.dims
    sq = not cells.legacy and dims >= 2          # 5.0 compares squared lengths
    metric = (lambda a, b: _sum((x - y) * (x - y) for x, y in zip(a, b))) if sq else \
        (lambda a, b: np.sqrt(_sum((x - y) * (x - y) for x, y in zip(a, b))))
    best = np.full(n, FLT_MAX if not cells.legacy else F32(8.0), dtype=F32)
    if dims == 1:
        best = np.full(n, FLT_MAX, dtype=F32)
    closest = tuple(np.zeros(n, dtype=F32) for _ in coord)
    c_off = tuple(np.zeros(n, dtype=np.int64) for _ in coord)
    for off in _offsets(dims, 1):
        pp = _point_pos(cells, grid, off, randomness)
        d = metric(pp, local)
        m = d < best
        best = np.where(m, d, best)
        closest = _sel(m, pp, closest)
        c_off = tuple(np.where(m, o, c) for o, c in zip(off, c_off))
    best = np.full(n, FLT_MAX if not cells.legacy else F32(8.0), dtype=F32)
    if dims == 1:
        best = np.full(n, FLT_MAX, dtype=F32)
    ctc = tuple(np.zeros(n, dtype=F32) for _ in coord)
    for off in _offsets(dims, 1):
        if all(o == 0 for o in off):
            continue
        cell_off = tuple(o + c for o, c in zip(off, c_off))
        h = cells.point(grid, cell_off)
        pp = tuple(co.astype(F32) + hv * randomness for co, hv in zip(cell_off, h))
        d = metric(closest, pp)
        m = d < best
        best = np.where(m, d, best)
        ctc = _sel(m, pp, ctc)
    return np.sqrt(_sum((a - b) * (a - b) for a, b in zip(ctc, closest))) / F32(2.0)


def _octave(feature, cells, coord, randomness, smoothness):
    if feature == "F2":
        return f2(cells, coord, randomness)
    if feature == "SMOOTH_F1":
        smooth = smoothness != 0
        if smooth.all():
            return smooth_f1(cells, coord, randomness, smoothness)
        if smooth.any():
            a = smooth_f1(cells, coord, randomness, np.where(smooth, smoothness, F32(1.0)))
            b = f1(cells, coord, randomness)
            return (np.where(smooth, a[0], b[0]), _sel(smooth, a[1], b[1]), _sel(smooth, a[2], b[2]))
    return f1(cells, coord, randomness)


def fractal_voronoi(feature, cells, coord, par):
    """`fractal_voronoi_x_fx`: Distance, Color and Position summed over octaves like fBM."""
    detail, rough, lac = par["detail"], par["roughness"], par["lacunarity"]
    n = detail.shape
    zero_input = (detail == 0) | (rough == 0)
    amp = np.ones(n, dtype=F32)
    maxamp = np.zeros(n, dtype=F32)
    scale = np.ones(n, dtype=F32)
    dist = np.zeros(n, dtype=F32)
    col = tuple(np.zeros(n, dtype=F32) for _ in range(3))
    pos = tuple(np.zeros(n, dtype=F32) for _ in coord)
    top = int(np.ceil(detail.max())) if detail.size else 0
    rmd = detail - np.floor(detail)
    for i in range(top + 1):
        od, oc, op = _octave(feature, cells, tuple(c * scale for c in coord), par["randomness"],
                             par["smoothness"])
        if i == 0:
            z = zero_input
            maxamp = np.where(z, F32(1.0), maxamp)
            dist, col, pos = np.where(z, od, dist), _sel(z, oc, col), _sel(z, op, pos)
        live = ~zero_input
        acc = live & (F32(i) <= detail)
        rem = live & (F32(i) > detail) & (rmd != 0) & (i <= np.ceil(detail))
        opos = tuple(p / scale for p in op)
        if rem.any():
            maxamp = np.where(rem, mix(maxamp, maxamp + amp, rmd), maxamp)
            dist = np.where(rem, mix(dist, dist + od * amp, rmd), dist)
            col = _sel(rem, tuple(mix(c, c + o * amp, rmd) for c, o in zip(col, oc)), col)
            pos = _sel(rem, tuple(mix(p, mix(p, o, amp), rmd) for p, o in zip(pos, opos)), pos)
        maxamp = np.where(acc, maxamp + amp, maxamp)
        dist = np.where(acc, dist + od * amp, dist)
        col = _sel(acc, tuple(c + o * amp for c, o in zip(col, oc)), col)
        pos = _sel(acc, tuple(mix(p, o, amp) for p, o in zip(pos, opos)), pos)
        scale = np.where(acc, scale * lac, scale)
        amp = np.where(acc, amp * rough, amp)
    if par["normalize"]:
        dist = dist / (maxamp * par["max_distance"])
        col = tuple(c / maxamp for c in col)
    return dist, col, pos


def fractal_distance_to_edge(cells, coord, par):
    detail, rough, lac = par["detail"], par["roughness"], par["lacunarity"]
    maxd = par["max_distance"]
    n = detail.shape
    zero_input = (detail == 0) | (rough == 0)
    amp = np.ones(n, dtype=F32)
    maxamp = maxd.copy()
    scale = np.ones(n, dtype=F32)
    dist = np.full(n, F32(8.0), dtype=F32)
    top = int(np.ceil(detail.max())) if detail.size else 0
    rmd = detail - np.floor(detail)
    for i in range(top + 1):
        od = distance_to_edge(cells, tuple(c * scale for c in coord), par["randomness"])
        if i == 0:
            dist = np.where(zero_input, od, dist)
        live = ~zero_input
        acc = live & (F32(i) <= detail)
        rem = live & (F32(i) > detail) & (rmd != 0) & (i <= np.ceil(detail))
        if rem.any():
            lerp_amp = mix(maxamp, maxd / scale, amp)
            lerp_d = mix(dist, np.minimum(dist, od / scale), amp)
            maxamp = np.where(rem, mix(maxamp, lerp_amp, rmd), maxamp)
            dist = np.where(rem, mix(dist, np.minimum(dist, lerp_d), rmd), dist)
        maxamp = np.where(acc, mix(maxamp, maxd / scale, amp), maxamp)
        dist = np.where(acc, mix(dist, np.minimum(dist, od / scale), amp), dist)
        scale = np.where(acc, scale * lac, scale)
        amp = np.where(acc, amp * rough, amp)
    if par["normalize"]:
        dist = dist / maxamp
    return dist


def voronoi_texture(inputs: dict, props: dict, ctx) -> dict:
    n = points(inputs, ctx)
    version = version_of(ctx)
    dims = dims_of(props, "voronoi_dimensions", "Voronoi Texture")
    feature = choice(props, "feature", FEATURES, "F1", "Voronoi Texture")
    metric = choice(props, "distance", METRICS, "EUCLIDEAN", "Voronoi Texture")
    node_scale = scalar(inputs, "Scale", n, 5.0)
    coord3 = tuple(c * node_scale for c in vector(inputs, "Vector", n))
    w = scalar(inputs, "W", n, 0.0) * node_scale
    coord = (w,) if dims == 1 else (coord3 + (w,))[:dims]
    fractal = tuple(version) >= FRACTAL_SINCE
    par = {
        "detail": np.clip(scalar(inputs, "Detail", n, 0.0), F32(0), F32(15)) if fractal else np.zeros(n, F32),
        "roughness": np.clip(scalar(inputs, "Roughness", n, 0.5), F32(0), F32(1)),
        "lacunarity": scalar(inputs, "Lacunarity", n, 2.0),
        "smoothness": np.clip(scalar(inputs, "Smoothness", n, 1.0) / F32(2.0), F32(0), F32(0.5)),
        "randomness": np.clip(scalar(inputs, "Randomness", n, 1.0), F32(0), F32(1)),
        "normalize": bool(props.get("normalize", False)) and fractal,
    }
    exponent = scalar(inputs, "Exponent", n, 0.5)
    cells = Cells(dims, version, metric, exponent)
    zeros = np.zeros(n)
    out = {"Distance": zeros, "Color": np.zeros((3, n)), "Position": np.zeros((3, n)), "W": zeros,
           "Radius": zeros}
    half = F32(0.5) + F32(0.5) * par["randomness"]
    if feature == "DISTANCE_TO_EDGE":
        par["max_distance"] = half
        out["Distance"] = out_float(fractal_distance_to_edge(cells, coord, par))
        return out
    if feature == "N_SPHERE_RADIUS":
        out["Radius"] = out_float(n_sphere_radius(cells, coord, par["randomness"]))
        return out
    if dims == 1:
        maxd = half
    else:
        maxd = cells.distance(tuple(np.zeros(n, F32) for _ in range(dims)), tuple(half for _ in range(dims)))
    par["max_distance"] = maxd * (F32(2.0) if feature == "F2" else F32(1.0))
    dist, col, pos = fractal_voronoi(feature, cells, coord, par)
    with np.errstate(divide="ignore", invalid="ignore"):
        pos = tuple(np.where(node_scale != 0, p / node_scale, F32(0.0)) for p in pos)
    pos4 = ((zeros,) * 3 + pos) if dims == 1 else (pos + (zeros,) * (4 - dims))
    out["Distance"] = out_float(dist)
    out["Color"] = out_rows(*col)
    out["Position"] = out_rows(*pos4[:3])
    out["W"] = out_float(pos4[3])
    return out


KERNELS = {"ShaderNodeTexVoronoi": voronoi_texture}
