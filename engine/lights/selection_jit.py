"""The light tree's walk (engine/lights/selection.py `LightTree._tree_sample` and `_tree_pmf`)
compiled with numba: one loop over the rays, each walking down the levels, instead of one NumPy
pass over the whole wavefront per level and per bound.

The arithmetic is that of `importance`, `box_distance2` and `LightTree._left_probability`, in
the same order and the same precision (float32 for the importance, float64 for the probabilities),
so the lights drawn and the pmfs are the same bit for bit (tests/lights/test_selection_jit.py).
Imported only through engine/core/backend.py's choice (it imports numba).
"""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)
inline = nb.njit(cache=True, error_model="numpy", nogil=True, inline="always")     # inlined into its callers

F0, F1 = np.float32(0.0), np.float32(1.0)
TINY = np.float32(1e-30)                 # selection.TINY
BELOW_ONE = np.nextafter(1.0, 0.0)
SIN_O = 16                               # the node table's extra column: sin of the cone's half-angle


@inline
def _max(a, b):
    """np.maximum of two scalars (NaN wins, as in NumPy)."""
    return a if (a >= b or a != a) else b


@inline
def _importance(x0, x1, x2, n0, n1, n2, t, oriented):
    """selection.importance of the node whose row of the node table is t (columns as
    selection.LightTree's level tables, then SIN_O).  Every branch is a select (both sides computed:
    the same numbers, no mispredicted jumps: 1.45x the branching form on a many-lights render's walks)."""
    w0, w1, w2 = t[0] - x0, t[1] - x1, t[2] - x2
    inv_d = F1 / np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    s = t[12] * inv_d
    inside = not s < F1
    sin_u = F0 if inside else s
    cos_u = -F1 if inside else np.sqrt(F1 - s * s)
    cos_i = (n0 * w0 + n1 * w1 + n2 * w2) * inv_d
    sin_i = np.sqrt(_max(F1 - cos_i * cos_i, F0))
    cos_r = F1 if (inside or cos_i > cos_u) else cos_i * cos_u + sin_i * sin_u
    g0 = _max(_max(t[3] - x0, x0 - t[6]), F0)
    g1 = _max(_max(t[4] - x1, x1 - t[7]), F0)
    g2 = _max(_max(t[5] - x2, x2 - t[8]), F0)
    near2 = g0 * g0 + g1 * g1 + g2 * g2
    result = t[14] * _max(cos_r, F0) / _max(_max(near2, t[15]), TINY)
    cos_o, sin_o = t[13], t[SIN_O]
    cos_t = -(t[9] * w0 + t[10] * w1 + t[11] * w2) * inv_d
    sin_t = np.sqrt(_max(F1 - cos_t * cos_t, F0))
    beyond = cos_t <= cos_o
    cos_a = cos_t * cos_o + sin_t * sin_o if beyond else F1
    sin_a = sin_t * cos_o - cos_t * sin_o if beyond else F0
    cos_e = F1 if (inside or cos_a > cos_u) else cos_a * cos_u + sin_a * sin_u
    emitter_side = result * _max(cos_e, F0)
    return emitter_side if oriented else result


@jit
def _left_probability(x0, x1, x2, n0, n1, n2, c, nodes, power, empty, oriented):
    """LightTree._left_probability for a receiver (float32) and the left child, node c of the table,
    of a level whose emitter-side test is `oriented`."""
    i_left = _importance(x0, x1, x2, n0, n1, n2, nodes[c], oriented)
    i_right = _importance(x0, x1, x2, n0, n1, n2, nodes[c + 1], oriented)
    total = i_left + i_right
    p_left, p_right = power[c], power[c + 1]
    by_power = p_left / _max(p_left + p_right, 1e-300) if p_left + p_right > 0.0 else 0.5
    p = np.float64(i_left / total) if total > F0 else by_power
    return 1.0 if empty[c + 1] else (0.0 if empty[c] else p)


@jit
def _walk(x0, x1, x2, n0, n1, n2, ui, nodes, power, empty, oriented, base, depth, count, light_at):
    """(light, tree pmf) of one receiver drawn with ui: LightTree._tree_sample's walk."""
    node, q = 0, 1.0
    for level in range(1, depth + 1):
        left = 2 * node
        p = _left_probability(x0, x1, x2, n0, n1, n2, base[level] + left, nodes, power, empty, oriented[level])
        go_left = ui < p
        ui = ui / p if go_left else (ui - p) / (1.0 - p)
        ui = 0.0 if ui != ui else ui                     # np.nan_to_num, then np.clip
        ui = min(max(ui, 0.0), BELOW_ONE)
        q *= p if go_left else 1.0 - p
        node = left if go_left else left + 1
    return light_at[(count * node) >> depth], q


@jit
def _walk_pmf(x0, x1, x2, n0, n1, n2, position, nodes, power, empty, oriented, base, depth, count):
    """The tree pmf of the light at sorted `position` for one receiver: LightTree._tree_pmf's walk."""
    node, q = 0, 1.0
    for level in range(1, depth + 1):
        left = 2 * node
        go_left = position < (count * (left + 1)) >> level
        p = _left_probability(x0, x1, x2, n0, n1, n2, base[level] + left, nodes, power, empty, oriented[level])
        q *= p if go_left else 1.0 - p
        node = left if go_left else left + 1
    return q


@jit
def tree_sample(x, n, u, nodes, power, empty, oriented, base, depth, count, light_at):
    """(light, tree pmf) per ray: LightTree._tree_sample (x, n float32 rows)."""
    m = u.shape[0]
    light = np.empty(m, np.int64)
    pmf = np.empty(m, np.float64)
    for i in range(m):
        light[i], pmf[i] = _walk(x[0, i], x[1, i], x[2, i], n[0, i], n[1, i], n[2, i], u[i], nodes, power, empty,
                                 oriented, base, depth, count, light_at)
    return light, pmf


@jit
def tree_pmf(x, n, light, nodes, power, empty, oriented, base, depth, count, position_of):
    """The tree pmf of each ray's light: LightTree._tree_pmf (x, n float32 rows)."""
    m = light.shape[0]
    pmf = np.empty(m, np.float64)
    for i in range(m):
        pmf[i] = _walk_pmf(x[0, i], x[1, i], x[2, i], n[0, i], n[1, i], n[2, i], position_of[light[i]], nodes,
                           power, empty, oriented, base, depth, count)
    return pmf


BLOCK = 64                               # rays walked together, level by level (select, mixed_pmf)


@jit
def _walk_block(xs, size, node, target, ui, q, il, ir, nodes, power, empty, oriented, base, depth, count):
    """The walks of `size` receivers (xs: their float32 x and n rows) together, level by level:
    per level one loop of the two children's importances over the block, then one of
    _left_probability's rest and _walk's (target < 0: by ui) or _walk_pmf's (towards sorted
    position target) step.  Each receiver's numbers are those of _walk and _walk_pmf; only the
    order of the receivers' operations changes (independent walks side by side instead of one
    walk's chain of dependent square roots and divisions at a time: 1.4x on many_lights' walks)."""
    for level in range(1, depth + 1):
        orient, c0 = oriented[level], base[level]
        for b in range(size):
            c = c0 + 2 * node[b]
            il[b] = _importance(xs[0, b], xs[1, b], xs[2, b], xs[3, b], xs[4, b], xs[5, b], nodes[c], orient)
            ir[b] = _importance(xs[0, b], xs[1, b], xs[2, b], xs[3, b], xs[4, b], xs[5, b], nodes[c + 1], orient)
        for b in range(size):
            left = 2 * node[b]
            c = c0 + left
            i_left = il[b]
            total = i_left + ir[b]
            p_left, p_right = power[c], power[c + 1]
            by_power = p_left / _max(p_left + p_right, 1e-300) if p_left + p_right > 0.0 else 0.5
            p = np.float64(i_left / total) if total > F0 else by_power
            p = 1.0 if empty[c + 1] else (0.0 if empty[c] else p)
            if target[b] >= 0:
                go_left = target[b] < (count * (left + 1)) >> level
            else:
                w = ui[b]
                go_left = w < p
                w = w / p if go_left else (w - p) / (1.0 - p)
                w = 0.0 if w != w else w                 # np.nan_to_num, then np.clip
                ui[b] = min(max(w, 0.0), BELOW_ONE)
            q[b] *= p if go_left else 1.0 - p
            node[b] = left if go_left else left + 1


@jit
def select(x, n, u, nodes, power, empty, oriented, base, depth, count, light_at, position_of, prob, cdf, defensive):
    """LightTree.sample, BLOCK rays at a time (x, n float64 rows, rounded to float32 per ray as the
    NumPy path's astype): u < defensive picks by the power pmf (PowerSelection.sample on u /
    defensive) and walks the tree for that light's pmf, else the tree's walk on the rescaled u;
    the pmf mixed as there (_walk_block)."""
    m = u.shape[0]
    light = np.empty(m, np.int64)
    pmf = np.empty(m, np.float64)
    last = cdf[count - 1]
    xs = np.empty((6, BLOCK), np.float32)
    node, target = np.empty(BLOCK, np.int64), np.empty(BLOCK, np.int64)
    ui, q = np.empty(BLOCK, np.float64), np.empty(BLOCK, np.float64)
    il, ir = np.empty(BLOCK, np.float32), np.empty(BLOCK, np.float32)
    for start in range(0, m, BLOCK):
        size = min(BLOCK, m - start)
        for b in range(size):
            i = start + b
            for c in range(3):
                xs[c, b], xs[3 + c, b] = np.float32(x[c, i]), np.float32(n[c, i])
            node[b], q[b], ui[b], target[b] = 0, 1.0, 0.0, -1
            if u[i] < defensive:
                v = u[i] / defensive * last              # np.searchsorted(cdf, v, side="right"), then min
                lo, hi = 0, count
                while lo < hi:
                    mid = (lo + hi) >> 1
                    if v < cdf[mid]:
                        hi = mid
                    else:
                        lo = mid + 1
                k = min(lo, count - 1)
                light[i], target[b] = k, position_of[k]
            else:
                ui[b] = (u[i] - defensive) / (1.0 - defensive)
        _walk_block(xs, size, node, target, ui, q, il, ir, nodes, power, empty, oriented, base, depth, count)
        for b in range(size):
            i = start + b
            if target[b] < 0:
                light[i] = light_at[(count * node[b]) >> depth]
            pmf[i] = defensive * prob[light[i]] + (1.0 - defensive) * q[b]
    return light, pmf


@jit
def mixed_pmf(x, n, light, nodes, power, empty, oriented, base, depth, count, position_of, prob, defensive):
    """LightTree.pmf, BLOCK rays at a time (x, n float64 rows, rounded to float32 per ray)."""
    m = light.shape[0]
    pmf = np.empty(m, np.float64)
    xs = np.empty((6, BLOCK), np.float32)
    node, target = np.empty(BLOCK, np.int64), np.empty(BLOCK, np.int64)
    ui, q = np.empty(BLOCK, np.float64), np.empty(BLOCK, np.float64)
    il, ir = np.empty(BLOCK, np.float32), np.empty(BLOCK, np.float32)
    for start in range(0, m, BLOCK):
        size = min(BLOCK, m - start)
        for b in range(size):
            i = start + b
            for c in range(3):
                xs[c, b], xs[3 + c, b] = np.float32(x[c, i]), np.float32(n[c, i])
            node[b], q[b], ui[b], target[b] = 0, 1.0, 0.0, position_of[light[i]]
        _walk_block(xs, size, node, target, ui, q, il, ir, nodes, power, empty, oriented, base, depth, count)
        for b in range(size):
            pmf[start + b] = defensive * prob[light[start + b]] + (1.0 - defensive) * q[b]
    return pmf


class TreeTables:
    """A LightTree's level tables joined into the flat arrays the kernels read: level L's node j
    is row base[L] + j of `nodes` (node-major: one node's 17 float32 columns in one cache line's
    reach), whose columns are the level table's rows and SIN_O, sqrt(max(1 - cos_o^2, 0)) in
    float32 as `importance` computes it per ray."""

    def __init__(self, tree):
        levels = tree.levels[1:]
        self.depth, self.count = tree.depth, tree.count
        self.base = np.zeros(tree.depth + 1, np.int64)
        self.base[1:] = np.cumsum([0] + [lv["table"].shape[1] for lv in levels])[:-1]
        table = np.concatenate([lv["table"] for lv in levels], axis=1).astype(np.float32)
        cos_o = table[13]
        sin_o = np.sqrt(np.maximum(np.float32(1.0) - cos_o * cos_o, np.float32(0.0)))
        self.nodes = np.ascontiguousarray(np.vstack([table, sin_o[None]]).T, np.float32)
        self.power = np.concatenate([lv["power"] for lv in levels]).astype(np.float64)
        self.empty = np.concatenate([lv["empty"] for lv in levels]).astype(np.bool_)
        self.oriented = np.array([False] + [lv["oriented"] for lv in levels], np.bool_)
        self.light_at = np.ascontiguousarray(tree.light_at, np.int64)
        self.position_of = np.ascontiguousarray(tree.position_of, np.int64)
        self.prob = np.ascontiguousarray(tree.fallback.prob, np.float64)
        self.cdf = np.ascontiguousarray(tree.fallback.cdf, np.float64)

    def _tables(self):
        return self.nodes, self.power, self.empty, self.oriented, self.base, self.depth, self.count

    def sample(self, x, n, u):
        """LightTree._tree_sample (x, n: float32 rows)."""
        return tree_sample(_rows32(x), _rows32(n), np.ascontiguousarray(u, np.float64), *self._tables(), self.light_at)

    def pmf(self, x, n, light):
        """LightTree._tree_pmf (x, n: float32 rows)."""
        return tree_pmf(_rows32(x), _rows32(n), np.ascontiguousarray(light, np.int64), *self._tables(),
                        self.position_of)

    def select(self, x, n, u, defensive):
        """LightTree.sample, defensive mixing included (x, n: float64 rows)."""
        return select(_rows64(x), _rows64(n), np.ascontiguousarray(u, np.float64), *self._tables(), self.light_at,
                      self.position_of, self.prob, self.cdf, defensive)

    def mixed_pmf(self, x, n, light, defensive):
        """LightTree.pmf, defensive mixing included (x, n: float64 rows)."""
        return mixed_pmf(_rows64(x), _rows64(n), np.ascontiguousarray(light, np.int64), *self._tables(),
                         self.position_of, self.prob, defensive)


def _rows32(a):
    return np.ascontiguousarray(a, np.float32)


def _rows64(a):
    return np.ascontiguousarray(a, np.float64)


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes (the tables of a tree of two lights)."""
    tables = TreeTables.__new__(TreeTables)
    tables.nodes, tables.power, tables.empty = np.ones((2, 17), np.float32), np.ones(2), np.zeros(2, np.bool_)
    tables.oriented, tables.base, tables.depth, tables.count = np.array([False, True]), np.zeros(2, np.int64), 1, 2
    tables.light_at = tables.position_of = np.arange(2, dtype=np.int64)
    tables.prob, tables.cdf = np.full(2, 0.5), np.array([0.5, 1.0])
    x, n, u = np.zeros((3, 4)), np.ones((3, 4)), np.linspace(0.0, 0.9, 4)
    light, _ = tables.sample(x, n, u)
    tables.pmf(x, n, light)
    tables.select(x, n, u, 0.05)
    tables.mixed_pmf(x, n, light, 0.05)
