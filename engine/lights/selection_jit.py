"""The light tree's walk (engine/lights/selection.py `LightTree._tree_sample` and `_tree_pmf`)
compiled with numba: the rays' walks down the levels in compiled loops, instead of one NumPy pass
over the whole wavefront per level and per bound.

The arithmetic is that of `importance`, `box_distance2` and `LightTree._left_probability`, in
the same order and the same precision (float32 for the importance, float64 for the probabilities),
so the lights drawn and the pmfs are the same bit for bit (tests/lights/test_selection_jit.py).
The walks of BLOCK rays go side by side, level by level (`_walks`), the importances of a level in
a loop LLVM vectorises (`_lane_importances`).
Imported only through engine/core/backend.py's choice (it imports numba).
"""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from ..sampling.search_jit import search_right

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


BLOCK = 64                               # rays walked together, level by level
COLS = 17                                # columns of a node's row (TreeTables)
LEFT, RIGHT = 6, 6 + COLS                # lane rows of the two children's columns
ROOT, ROOT_RIGHT = 6 + 2 * COLS + 2, 6 + 3 * COLS + 2   # the root's two children's, filled once per call
ROWS = ROOT + 2 * COLS                   # lane rows: x (3), n (3), two children's 17 columns, their
#                                          importances, the root's children (level 1: every walk's pair)


@jit
def _lane_importances(lane, size, oriented, col, dst):
    """selection.importance for lanes b < size of a block, into lane row dst: lane[k * BLOCK + b]
    holds row k (x0 x1 x2 n0 n1 n2 of the receiver; from row col on the columns of the node's row of
    the node table).  Every branch is a select, so both sides are computed (the same numbers).  One
    flat array whose rows are at constant offsets: LLVM vectorises the loop (rows of several arrays
    at runtime strides need more runtime overlap checks than its limit: scalar code)."""
    for b in range(size):
        x0, x1, x2 = lane[b], lane[BLOCK + b], lane[2 * BLOCK + b]
        n0, n1, n2 = lane[3 * BLOCK + b], lane[4 * BLOCK + b], lane[5 * BLOCK + b]
        t = col * BLOCK + b                      # column k of the node: lane[t + k * BLOCK]
        w0, w1, w2 = lane[t] - x0, lane[t + BLOCK] - x1, lane[t + 2 * BLOCK] - x2
        inv_d = F1 / np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        s = lane[t + 12 * BLOCK] * inv_d
        inside = not s < F1
        sin_u = F0 if inside else s
        cos_u = -F1 if inside else np.sqrt(F1 - s * s)
        cos_i = (n0 * w0 + n1 * w1 + n2 * w2) * inv_d
        sin_i = np.sqrt(_max(F1 - cos_i * cos_i, F0))
        cos_r = F1 if (inside or cos_i > cos_u) else cos_i * cos_u + sin_i * sin_u
        g0 = _max(_max(lane[t + 3 * BLOCK] - x0, x0 - lane[t + 6 * BLOCK]), F0)
        g1 = _max(_max(lane[t + 4 * BLOCK] - x1, x1 - lane[t + 7 * BLOCK]), F0)
        g2 = _max(_max(lane[t + 5 * BLOCK] - x2, x2 - lane[t + 8 * BLOCK]), F0)
        near2 = g0 * g0 + g1 * g1 + g2 * g2
        result = lane[t + 14 * BLOCK] * _max(cos_r, F0) / _max(_max(near2, lane[t + 15 * BLOCK]), TINY)
        cos_o, sin_o = lane[t + 13 * BLOCK], lane[t + SIN_O * BLOCK]
        cos_t = -(lane[t + 9 * BLOCK] * w0 + lane[t + 10 * BLOCK] * w1 + lane[t + 11 * BLOCK] * w2) * inv_d
        sin_t = np.sqrt(_max(F1 - cos_t * cos_t, F0))
        beyond = cos_t <= cos_o
        cos_a = cos_t * cos_o + sin_t * sin_o if beyond else F1
        sin_a = sin_t * cos_o - cos_t * sin_o if beyond else F0
        cos_e = F1 if (inside or cos_a > cos_u) else cos_a * cos_u + sin_a * sin_u
        emitter_side = result * _max(cos_e, F0)
        lane[dst * BLOCK + b] = emitter_side if oriented else result


IL, IR = 6 + 2 * COLS, 6 + 2 * COLS + 1  # the lane rows of the children's importances
UI, Q, PL, PR = 0, 1, 2, 3               # rows of the float64 state lanes
NODE, TARGET, EL, ER = 0, 1, 2, 3        # rows of the int64 state lanes


@jit
def _lane_steps(lane, st, it, size, level, count):
    """One level's step of each lane: LightTree._left_probability's rest and _tree_sample's (target
    < 0: by ui) or _tree_pmf's step, both sides computed and selected (a loop LLVM vectorises: three
    lane arrays, rows at constant offsets)."""
    for b in range(size):
        left = 2 * it[NODE * BLOCK + b]
        i_left = lane[IL * BLOCK + b]
        total = i_left + lane[IR * BLOCK + b]
        p_left, p_right = st[PL * BLOCK + b], st[PR * BLOCK + b]
        by_power = p_left / _max(p_left + p_right, 1e-300) if p_left + p_right > 0.0 else 0.5
        p = np.float64(i_left / total) if total > F0 else by_power
        p = 1.0 if it[ER * BLOCK + b] != 0 else (0.0 if it[EL * BLOCK + b] != 0 else p)   # never an empty child
        target = it[TARGET * BLOCK + b]
        w = st[UI * BLOCK + b]
        go_left = (target < (count * (left + 1)) >> level) if target >= 0 else w < p
        w = w / p if go_left else (w - p) / (1.0 - p)
        w = 0.0 if w != w else w                         # np.nan_to_num, then np.clip
        w = min(max(w, 0.0), BELOW_ONE)
        st[UI * BLOCK + b] = st[UI * BLOCK + b] if target >= 0 else w
        st[Q * BLOCK + b] *= p if go_left else 1.0 - p
        it[NODE * BLOCK + b] = left if go_left else left + 1


@inline
def _fill_node(lane, row, b, nodes, c, oriented):
    """Node c's columns into lane b from lane row `row` on: centre, lo, hi (0-8), radius (12), power
    (14) and min2 (15), and on an oriented level the cone's axis (9-11), cos_o (13) and SIN_O too
    (else those lanes keep numbers the importance computes with and then drops: `emitter_side if
    oriented else result`).  Written as ranges: a loop over a tuple of columns cost 40 % more."""
    for k in range(9):
        lane[(row + k) * BLOCK + b] = nodes[c, k]
    for k in range(12, 16, 2):
        lane[(row + k) * BLOCK + b] = nodes[c, k]
    lane[(row + 15) * BLOCK + b] = nodes[c, 15]
    if oriented:
        for k in range(9, 12):
            lane[(row + k) * BLOCK + b] = nodes[c, k]
        lane[(row + 13) * BLOCK + b] = nodes[c, 13]
        lane[(row + SIN_O) * BLOCK + b] = nodes[c, SIN_O]


@jit
def _walks(x, n, ui, target, nodes, power, empty, oriented, base, depth, count, node, q):
    """The tree walks of all receivers (x, n rows, rounded to float32 per ray), BLOCK at a time and
    level by level: a receiver with target < 0 draws with ui (LightTree._tree_sample: ui is rescaled
    in place), one with a sorted light position `target` walks towards it (LightTree._tree_pmf);
    node gets each walk's leaf, q its tree pmf.  Per level: the two children's node-table rows,
    powers and emptiness copied into the lanes, their importances (_lane_importances), then the
    steps (_lane_steps): per receiver the operations of the NumPy walk in its order (the same bits),
    the block's walks side by side in vectorised loops instead of one walk's chain of dependent
    square roots and divisions at a time.
    The copies into the lanes cost more than the importances, so only the needed ones are made:
    level 1's pair (the root's children, every walk's) is copied once per call into lane rows of
    its own (ROOT); a pair with an empty child is not copied (the step takes the other child
    whatever the importances); a level of two-sided nodes copies no cone (_fill_node)."""
    m = ui.shape[0]
    lane = np.zeros(ROWS * BLOCK, np.float32)       # zeros: no NaN or denormal in lanes never filled
    st = np.empty(4 * BLOCK, np.float64)
    it = np.zeros(4 * BLOCK, np.int64)
    if depth >= 1:
        for b in range(BLOCK):
            for k in range(COLS):
                lane[(ROOT + k) * BLOCK + b] = nodes[base[1], k]
                lane[(ROOT_RIGHT + k) * BLOCK + b] = nodes[base[1] + 1, k]
    for start in range(0, m, BLOCK):
        size = min(BLOCK, m - start)
        for c in range(3):
            for b in range(size):
                lane[c * BLOCK + b] = np.float32(x[c, start + b])
                lane[(3 + c) * BLOCK + b] = np.float32(n[c, start + b])
        for b in range(size):
            it[NODE * BLOCK + b], it[TARGET * BLOCK + b] = 0, target[start + b]
            st[UI * BLOCK + b], st[Q * BLOCK + b] = ui[start + b], 1.0
        for level in range(1, depth + 1):
            c0 = base[level]
            for b in range(size):
                c = c0 + 2 * it[NODE * BLOCK + b]
                st[PL * BLOCK + b], st[PR * BLOCK + b] = power[c], power[c + 1]
                it[EL * BLOCK + b], it[ER * BLOCK + b] = empty[c], empty[c + 1]
                if level > 1 and not (empty[c] or empty[c + 1]):
                    _fill_node(lane, LEFT, b, nodes, c, oriented[level])
                    _fill_node(lane, RIGHT, b, nodes, c + 1, oriented[level])
            if level == 1:          # (the rows as literals, each call compiled for its own: vectorised)
                _lane_importances(lane, size, oriented[level], ROOT, IL)
                _lane_importances(lane, size, oriented[level], ROOT_RIGHT, IR)
            else:
                _lane_importances(lane, size, oriented[level], LEFT, IL)
                _lane_importances(lane, size, oriented[level], RIGHT, IR)
            _lane_steps(lane, st, it, size, level, count)
        for b in range(size):
            node[start + b], q[start + b] = it[NODE * BLOCK + b], st[Q * BLOCK + b]
            ui[start + b] = st[UI * BLOCK + b]


@jit
def tree_sample(x, n, u, nodes, power, empty, oriented, base, depth, count, light_at):
    """(light, tree pmf) per ray: LightTree._tree_sample (x, n float32 rows)."""
    m = u.shape[0]
    node, pmf = np.empty(m, np.int64), np.empty(m, np.float64)
    _walks(x, n, u.copy(), np.full(m, -1, np.int64), nodes, power, empty, oriented, base, depth, count, node, pmf)
    light = np.empty(m, np.int64)
    for i in range(m):
        light[i] = light_at[(count * node[i]) >> depth]
    return light, pmf


@jit
def tree_pmf(x, n, light, nodes, power, empty, oriented, base, depth, count, position_of):
    """The tree pmf of each ray's light: LightTree._tree_pmf (x, n float32 rows)."""
    m = light.shape[0]
    node, pmf = np.empty(m, np.int64), np.empty(m, np.float64)
    target = np.empty(m, np.int64)
    for i in range(m):
        target[i] = position_of[light[i]]
    _walks(x, n, np.zeros(m), target, nodes, power, empty, oriented, base, depth, count, node, pmf)
    return pmf


@jit
def select(x, n, u, nodes, power, empty, oriented, base, depth, count, light_at, position_of, prob, cdf, defensive):
    """LightTree.sample (x, n float64 rows, rounded to float32 per ray as the NumPy path's astype):
    u < defensive picks by the power pmf (PowerSelection.sample on u / defensive) and walks the tree
    for that light's pmf, else the tree's walk on the rescaled u; the pmf mixed as there."""
    m = u.shape[0]
    light, target = np.empty(m, np.int64), np.full(m, -1, np.int64)
    ui, node, q = np.zeros(m), np.empty(m, np.int64), np.empty(m, np.float64)
    last = cdf[count - 1]
    for i in range(m):
        if u[i] < defensive:
            v = u[i] / defensive * last              # np.searchsorted(cdf, v, side="right"), then min
            k = min(search_right(cdf, count, v), count - 1)
            light[i], target[i] = k, position_of[k]
        else:
            ui[i] = (u[i] - defensive) / (1.0 - defensive)
    _walks(x, n, ui, target, nodes, power, empty, oriented, base, depth, count, node, q)
    pmf = np.empty(m, np.float64)
    for i in range(m):
        if target[i] < 0:
            light[i] = light_at[(count * node[i]) >> depth]
        pmf[i] = defensive * prob[light[i]] + (1.0 - defensive) * q[i]
    return light, pmf


@jit
def mixed_pmf(x, n, light, nodes, power, empty, oriented, base, depth, count, position_of, prob, defensive):
    """LightTree.pmf (x, n float64 rows, rounded to float32 per ray)."""
    m = light.shape[0]
    q = tree_pmf(x, n, light, nodes, power, empty, oriented, base, depth, count, position_of)
    pmf = np.empty(m, np.float64)
    for i in range(m):
        pmf[i] = defensive * prob[light[i]] + (1.0 - defensive) * q[i]
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
