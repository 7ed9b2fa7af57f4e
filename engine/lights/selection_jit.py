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

F0, F1 = np.float32(0.0), np.float32(1.0)
TINY = np.float32(1e-30)                 # selection.TINY
BELOW_ONE = np.nextafter(1.0, 0.0)


@jit
def _max(a, b):
    """np.maximum of two scalars (NaN wins, as in NumPy)."""
    return a if (a >= b or a != a) else b


@jit
def _importance(x0, x1, x2, n0, n1, n2, t, c, oriented):
    """selection.importance of node column c of the level table t (rows as selection.LightTree)."""
    w0, w1, w2 = t[0, c] - x0, t[1, c] - x1, t[2, c] - x2
    inv_d = F1 / np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    s = t[12, c] * inv_d
    inside = not s < F1
    if inside:
        sin_u, cos_u = F0, -F1
    else:
        sin_u, cos_u = s, np.sqrt(F1 - s * s)
    cos_i = (n0 * w0 + n1 * w1 + n2 * w2) * inv_d
    sin_i = np.sqrt(_max(F1 - cos_i * cos_i, F0))
    cos_r = F1 if (inside or cos_i > cos_u) else cos_i * cos_u + sin_i * sin_u
    g0 = _max(_max(t[3, c] - x0, x0 - t[6, c]), F0)
    g1 = _max(_max(t[4, c] - x1, x1 - t[7, c]), F0)
    g2 = _max(_max(t[5, c] - x2, x2 - t[8, c]), F0)
    near2 = g0 * g0 + g1 * g1 + g2 * g2
    result = t[14, c] * _max(cos_r, F0) / _max(_max(near2, t[15, c]), TINY)
    if oriented:
        cos_o = t[13, c]
        cos_t = -(t[9, c] * w0 + t[10, c] * w1 + t[11, c] * w2) * inv_d
        sin_t = np.sqrt(_max(F1 - cos_t * cos_t, F0))
        sin_o = np.sqrt(_max(F1 - cos_o * cos_o, F0))
        if cos_t <= cos_o:
            cos_a, sin_a = cos_t * cos_o + sin_t * sin_o, sin_t * cos_o - cos_t * sin_o
        else:
            cos_a, sin_a = F1, F0
        cos_e = F1 if (inside or cos_a > cos_u) else cos_a * cos_u + sin_a * sin_u
        result = result * _max(cos_e, F0)
    return result


@jit
def _left_probability(x, n, i, level, left, table, power, empty, oriented, base):
    """LightTree._left_probability for ray i and the left child `left` of a node of `level`."""
    c = base[level] + left
    x0, x1, x2, n0, n1, n2 = x[0, i], x[1, i], x[2, i], n[0, i], n[1, i], n[2, i]
    i_left = _importance(x0, x1, x2, n0, n1, n2, table, c, oriented[level])
    i_right = _importance(x0, x1, x2, n0, n1, n2, table, c + 1, oriented[level])
    total = i_left + i_right
    p_left, p_right = power[c], power[c + 1]
    by_power = p_left / _max(p_left + p_right, 1e-300) if p_left + p_right > 0.0 else 0.5
    p = np.float64(i_left / total) if total > F0 else by_power
    if empty[c + 1]:
        return 1.0
    if empty[c]:
        return 0.0
    return p


@jit
def tree_sample(x, n, u, table, power, empty, oriented, base, depth, count, light_at):
    """(light, tree pmf) per ray: LightTree._tree_sample."""
    m = u.shape[0]
    light = np.empty(m, np.int64)
    pmf = np.empty(m, np.float64)
    for i in range(m):
        node, q, ui = 0, 1.0, u[i]
        for level in range(1, depth + 1):
            left = 2 * node
            p = _left_probability(x, n, i, level, left, table, power, empty, oriented, base)
            go_left = ui < p
            ui = ui / p if go_left else (ui - p) / (1.0 - p)
            if ui != ui:                                 # np.nan_to_num, then np.clip
                ui = 0.0
            ui = min(max(ui, 0.0), BELOW_ONE)
            q *= p if go_left else 1.0 - p
            node = left if go_left else left + 1
        light[i] = light_at[(count * node) >> depth]
        pmf[i] = q
    return light, pmf


@jit
def tree_pmf(x, n, light, table, power, empty, oriented, base, depth, count, position_of):
    """The tree pmf of each ray's light: LightTree._tree_pmf."""
    m = light.shape[0]
    pmf = np.empty(m, np.float64)
    for i in range(m):
        position = position_of[light[i]]
        node, q = 0, 1.0
        for level in range(1, depth + 1):
            left = 2 * node
            go_left = position < (count * (left + 1)) >> level
            p = _left_probability(x, n, i, level, left, table, power, empty, oriented, base)
            q *= p if go_left else 1.0 - p
            node = left if go_left else left + 1
        pmf[i] = q
    return pmf


class TreeTables:
    """A LightTree's level tables joined into the flat arrays the kernels read: level L's node j
    is column base[L] + j."""

    def __init__(self, tree):
        levels = tree.levels[1:]
        self.depth, self.count = tree.depth, tree.count
        self.base = np.zeros(tree.depth + 1, np.int64)
        self.base[1:] = np.cumsum([0] + [lv["table"].shape[1] for lv in levels])[:-1]
        self.table = np.ascontiguousarray(np.concatenate([lv["table"] for lv in levels], axis=1), np.float32)
        self.power = np.concatenate([lv["power"] for lv in levels]).astype(np.float64)
        self.empty = np.concatenate([lv["empty"] for lv in levels]).astype(np.bool_)
        self.oriented = np.array([False] + [lv["oriented"] for lv in levels], np.bool_)
        self.light_at = np.ascontiguousarray(tree.light_at, np.int64)
        self.position_of = np.ascontiguousarray(tree.position_of, np.int64)

    def sample(self, x, n, u):
        return tree_sample(_rows32(x), _rows32(n), np.ascontiguousarray(u, np.float64), self.table, self.power,
                           self.empty, self.oriented, self.base, self.depth, self.count, self.light_at)

    def pmf(self, x, n, light):
        return tree_pmf(_rows32(x), _rows32(n), np.ascontiguousarray(light, np.int64), self.table, self.power,
                        self.empty, self.oriented, self.base, self.depth, self.count, self.position_of)


def _rows32(a):
    return np.ascontiguousarray(a, np.float32)


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes (a tree of two lights)."""
    table = np.ones((16, 2), np.float32)
    power, empty, oriented, base = np.ones(2), np.zeros(2, np.bool_), np.array([False, True]), np.zeros(2, np.int64)
    x, n, u = np.zeros((3, 4), np.float32), np.ones((3, 4), np.float32), np.linspace(0.0, 0.9, 4)
    order = np.arange(2, dtype=np.int64)
    light, _ = tree_sample(x, n, u, table, power, empty, oriented, base, 1, 2, order)
    tree_pmf(x, n, light, table, power, empty, oriented, base, 1, 2, order)
