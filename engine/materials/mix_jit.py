"""engine/materials/mix.py's pair bookkeeping compiled with numba: the sample's pick of one (hit,
leaf) pair per hit and the per-hit sums of the pairs' weighted f cos and pdfs, each one loop instead
of some fifteen NumPy passes over the pairs, and the pairs (or hits) grouped by their leaf's row in
one counting pass (the same ascending places as np.flatnonzero per row); the pairs placed hit-major with
their leaves, rows, weights and colours (`place`) and their pick probabilities (`probabilities`), a row's
eval results scattered (`put`), a sample's leaf results written (`write_leaf`), its mixture's hits and pairs found
(`spread`) and its quotients written (`mixture`), each one loop instead of a handful of NumPy calls and
fancy scatters; and the Fresnel and Layer Weight factors' view of the hits (`view_factor`: dot(wo, n),
the backfacing test, engine/nodes/inputs.py fresnel_dielectric_cos and the clip to [0, 1] in one loop over
the hits a material has, instead of some twenty NumPy passes and the takes of the hits' view).  Imported
only through engine/core/backend.py's choice (it imports numba).

The same float64 operations in the same order: np.cumsum adds the probabilities one after another,
np.bincount adds each pair's product to its hit's sum in the pairs' order from 0, np.searchsorted
(side "right") counts the sums <= the target (NumPy's comparison: a NaN target counts them all), and
np.minimum / np.clip keep a NaN (tests/materials/test_mix_jit.py); np.nan_to_num(nan=1.0) makes NaN 1 and
+-inf the largest finite floats.  On a sorted table (the
cumulative sum of probabilities without NaN: every render's) that count, clipped to the hit's pairs,
is found by stepping through the hit's few pairs instead of a binary search of the whole table (any
correct search of a sorted table counts the same); a table with a NaN is searched as NumPy does."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from ..core.kernel_inputs import contiguous
from ..sampling.search_jit import search_right

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)
FLOAT_MAX = float(np.finfo(np.float64).max)


@jit
def _pick(hit, prob, total, u_lobe, u_max, chosen, p_c, u_leaf):
    count, n = hit.shape[0], total.shape[0]
    cum = np.empty(count)
    acc = 0.0
    ordered = True                                          # cum non-decreasing, without NaN
    for i in range(count):                                  # np.cumsum(prob)
        acc = prob[i] if i == 0 else acc + prob[i]
        cum[i] = acc
        if i > 0 and not cum[i - 1] <= acc:
            ordered = False
    if count and cum[0] != cum[0]:
        ordered = False
    j = 0
    for h in range(n):
        while j < count and hit[j] < h:                     # start: np.searchsorted(hit, h) (hit sorted)
            j += 1
        start = j
        k = j
        while k < count and hit[k] < h + 1:                 # stop: the next hit's start
            k += 1
        stop = k
        first = start if start < count - 1 else count - 1
        base = cum[first] - prob[first]
        u = u_lobe[h]
        if not u != u and u > u_max:                        # np.minimum(u_lobe, u_max): NaN stays NaN
            u = u_max
        target = base + u * (1.0 if total[h] > 0.0 else 0.0)
        if ordered:                                         # the count of sums <= target, from start on
            c = start
            while c < stop - 1 and cum[c] <= target:
                c += 1
            if target != target:                            # a NaN target counts them all
                c = count
        else:
            c = search_right(cum, count, target)            # np.searchsorted(cum, target, side="right")
        c = c if c > start else start                       # np.clip(c, start, stop - 1)
        c = c if c < stop - 1 else stop - 1
        chosen[h] = c
        pc = prob[c]
        p_c[h] = pc
        if pc > 0.0:
            x = (target - (cum[c] - pc)) / pc
            if x == x:                                      # np.clip(x, 0, u_max): NaN stays NaN
                x = x if x > 0.0 else 0.0
                x = x if x < u_max else u_max
            u_leaf[h] = x
        else:
            u_leaf[h] = 0.0


def pick(hit, prob, total, u_lobe, u_max):
    """(chosen pair (N,), its probability p_c (N,), the leaf's uniform u_leaf (N,)) as MixBSDF.sample
    picks them: the pairs hit-major (hit sorted, every hit with a pair), u_max = 1 - 1e-12."""
    n = len(total)
    chosen, p_c, u_leaf = np.empty(n, dtype=np.int64), np.empty(n), np.empty(n)
    _pick(np.ascontiguousarray(hit, np.int64), np.ascontiguousarray(prob, np.float64),
          np.ascontiguousarray(total, np.float64), np.ascontiguousarray(u_lobe, np.float64), float(u_max),
          chosen, p_c, u_leaf)
    return chosen, p_c, u_leaf


@jit
def _sums(hit, f_cos, weight, pdf, prob, f_sum, p_sum):
    for i in range(hit.shape[0]):
        h = hit[i]
        w = weight[i]
        f_sum[0, h] += f_cos[0, i] * w
        f_sum[1, h] += f_cos[1, i] * w
        f_sum[2, h] += f_cos[2, i] * w
        p_sum[h] += pdf[i] * prob[i]


def sums(hit, f_cos, weight, pdf, prob, n):
    """(sum of f_cos x weight (3, n), sum of pdf x prob (n,)) per hit over the pairs (hit (P,)): the
    np.bincount sums of MixBSDF._sum and its pdf."""
    f_sum, p_sum = np.zeros((3, n)), np.zeros(n)
    rows = np.ascontiguousarray
    _sums(rows(hit, np.int64), rows(f_cos, np.float64), rows(weight, np.float64), rows(pdf, np.float64),
          rows(prob, np.float64), f_sum, p_sum)
    return f_sum, p_sum


@jit
def _group(rows, keep, use_keep, n_codes, order, offsets):
    for c in range(n_codes + 1):
        offsets[c] = 0
    for i in range(rows.shape[0]):                          # how many places each code has
        r = rows[i]
        if 0 <= r < n_codes and (not use_keep or keep[i]):
            offsets[r + 1] += 1
    for c in range(n_codes):
        offsets[c + 1] += offsets[c]
    fill = offsets[:n_codes].copy()
    for i in range(rows.shape[0]):                          # each code's places, ascending
        r = rows[i]
        if 0 <= r < n_codes and (not use_keep or keep[i]):
            order[fill[r]] = i
            fill[r] += 1


def by_row(rows, keep, codes):
    """MixBSDF._by_row: [(r, the places (ascending) where `rows` (int) is r and `keep` (bool, or None:
    everywhere) is True)] for the codes r of `codes` (ascending list of non-negative ints) that have
    any; a counting sort of the places by row instead of one comparison and np.flatnonzero per row."""
    if not codes:
        return []
    n_codes = codes[-1] + 1
    order, offsets = np.empty(len(rows), np.int64), np.empty(n_codes + 1, np.int64)
    use_keep = keep is not None
    _group(np.ascontiguousarray(rows, np.int64),
           np.ascontiguousarray(keep, np.bool_) if use_keep else np.zeros(0, np.bool_), use_keep, n_codes,
           order, offsets)
    ends = offsets.tolist()                                 # Python ints: no NumPy scalar per comparison
    return [(r, order[ends[r]:ends[r + 1]]) for r in codes if ends[r + 1] > ends[r]]


@jit
def _place(material, leaf_count, leaf_table, row_table, weights, table_color):
    n, materials = material.shape[0], leaf_count.shape[0]
    size = 0
    for h in range(n):
        m = material[h]
        if m < 0 or m >= materials:
            raise IndexError("mix_jit.place: a material id outside the leaf table")
        if leaf_count[m] > leaf_table.shape[1]:
            raise IndexError("mix_jit.place: a material with more leaves than the table's columns")
        size += leaf_count[m]
    hit, leaf, row = np.empty(size, np.int64), np.empty(size, np.int64), np.empty(size, np.int64)
    weight, color = np.empty(size), np.empty((3, size))
    p = 0
    for h in range(n):                                      # hit-major: a hit's pairs in its leaves' order
        m = material[h]
        for j in range(leaf_count[m]):
            c = leaf_table[m, j]
            if c < 0 or c >= table_color.shape[1]:
                raise IndexError("mix_jit.place: a leaf outside the colour table")
            hit[p], leaf[p], row[p], weight[p] = h, c, row_table[m, j], weights[j, h]
            color[0, p], color[1, p], color[2, p] = table_color[0, c], table_color[1, c], table_color[2, c]
            p += 1
    return hit, leaf, row, weight, color


def place(material, leaf_count, leaf_table, row_table, weights, table_color):
    """MixBSDF._placed: every (hit, leaf) pair of hits of materials `material` (N,), hit-major: (hit,
    leaf material, row, weight, the leaf's table colour (3, P)).  leaf_count (M,): leaves per material;
    leaf_table, row_table (M, J): material m's j-th leaf and its row; weights (J, N): leaf j's weight at
    each hit (read for j < its material's count); table_color (3, materials).  One pass instead of a
    repeat, a cumulative sum and three scatters per leaf and the colours' gather."""
    if not (leaf_table.shape == row_table.shape and leaf_table.shape[0] == len(leaf_count)
            and weights.shape[1] == len(material) and weights.shape[0] >= leaf_table.shape[1]
            and table_color.shape[0] == 3):
        raise ValueError(f"mix_jit.place: tables {leaf_table.shape}, {row_table.shape}, weights {weights.shape} "
                         f"for {len(material)} hits of {len(leaf_count)} materials")
    return _place(contiguous(material, np.int64), contiguous(leaf_count, np.int64), contiguous(leaf_table, np.int64),
                  contiguous(row_table, np.int64), contiguous(weights), contiguous(table_color))


@jit
def _probabilities(hit, weight, color, floor, n):
    size = hit.shape[0]
    rate, prob, total = np.empty(size), np.empty(size), np.zeros(n)
    for p in range(size):
        h = hit[p]
        if h < 0 or h >= n:
            raise IndexError("mix_jit.probabilities: a pair's hit outside the hits")
        albedo = (color[0, p] + color[1, p] + color[2, p]) / 3.0
        if albedo < floor:                                  # np.maximum(albedo, floor): NaN stays NaN
            albedo = floor
        r = weight[p] * albedo
        rate[p] = r
        total[h] += r                                       # np.bincount: in the pairs' order from 0
    for p in range(size):
        t = total[hit[p]]
        prob[p] = rate[p] / t if t > 0.0 else 0.0
    return prob, total


def probabilities(hit, weight, color, floor, n):
    """MixBSDF._probabilities: (each pair's pick probability (P,), each hit's total weight x albedo
    (n,)), albedo the mean of the leaf colour (at least `floor`)."""
    if color.shape != (3, len(hit)) or weight.shape != hit.shape:
        raise ValueError(f"mix_jit.probabilities: hit {hit.shape}, weight {weight.shape}, color {color.shape}")
    return _probabilities(contiguous(hit, np.int64), contiguous(weight), contiguous(color), float(floor), int(n))


@jit
def _put(f_cos, pdf, k, f, p):
    for i in range(k.shape[0]):
        j = k[i]
        if j < 0 or j >= pdf.shape[0]:
            raise IndexError("mix_jit.put: a place outside the results")
        f_cos[0, j], f_cos[1, j], f_cos[2, j] = f[0, i], f[1, i], f[2, i]
        pdf[j] = p[i]


def put(f_cos, pdf, k, f, p):
    """f_cos[:, k], pdf[k] = f, p (MixBSDF._eval_pairs' scatter of a row's results) in one loop."""
    if f.shape != (3, len(k)) or p.shape != (len(k),) or f_cos.shape != (3, len(pdf)):
        raise ValueError(f"mix_jit.put: {f.shape}, {p.shape} at {len(k)} places of {f_cos.shape}")
    _put(f_cos, pdf, contiguous(k, np.int64), contiguous(f), contiguous(p))


@jit
def _write_leaf(mine, pairs, s_wi, s_value, s_pdf, s_flags, delta_lobe, weight, p_c, wi, value, pdf, flags, delta):
    n, size = pdf.shape[0], weight.shape[0]
    for i in range(mine.shape[0]):
        h, c = mine[i], pairs[i]
        if h < 0 or h >= n or c < 0 or c >= size:
            raise IndexError("mix_jit.write_leaf: a hit or pair outside the arrays")
        wi[0, h], wi[1, h], wi[2, h] = s_wi[0, i], s_wi[1, i], s_wi[2, i]
        flags[h] = s_flags[i]
        is_delta = (s_flags[i] & delta_lobe) != 0
        delta[h] = is_delta
        if is_delta:                                        # the leaf's own value and pdf
            w_over_p = weight[c] / p_c[h]
            value[0, h] = s_value[0, i] * w_over_p
            value[1, h] = s_value[1, i] * w_over_p
            value[2, h] = s_value[2, i] * w_over_p
            pdf[h] = p_c[h] * s_pdf[i]


def write_leaf(mine, pairs, s, delta_lobe, weight, p_c, wi, value, pdf, flags, delta):
    """MixBSDF._write_leaf: the leaf samples `s` (BSDFSample) of hits `mine` (their pairs `pairs`) written
    into the mixture's sample arrays (wi, value (3, N), pdf (N,), flags (N,) int8, delta (N,) bool) in one
    loop: wi and flags of each, value = the leaf's value x weight / p_c and pdf = p_c x its pdf where
    the leaf took a delta lobe (the others: the mixture's, later).  Refuses (ValueError) unless mine,
    pairs, s.pdf and s.flags have shape (m,), s.wi and s.value (3, m), weight one axis, p_c, pdf, flags
    and delta shape (N,) and wi and value (3, N), N = len(pdf); the kernel then refuses (IndexError) a
    hit of `mine` outside [0, N) and a pair outside the weights."""
    m, n = len(mine), len(pdf)
    if not (mine.shape == pairs.shape == s.pdf.shape == s.flags.shape == (m,) and s.wi.shape == s.value.shape == (3, m)
            and weight.ndim == 1 and p_c.shape == pdf.shape == flags.shape == delta.shape == (n,)
            and wi.shape == value.shape == (3, n)):
        raise ValueError(f"mix_jit.write_leaf: a sample of wi {s.wi.shape}, value {s.value.shape}, pdf {s.pdf.shape}, "
                         f"flags {s.flags.shape} for hits {mine.shape}, pairs {pairs.shape}; weight {weight.shape}, "
                         f"p_c {p_c.shape}, into wi {wi.shape}, value {value.shape}, pdf {pdf.shape}, "
                         f"flags {flags.shape}, delta {delta.shape}")
    _write_leaf(contiguous(mine, np.int64), contiguous(pairs, np.int64), contiguous(s.wi), contiguous(s.value),
                contiguous(s.pdf), contiguous(s.flags, np.int64), int(delta_lobe), contiguous(weight), contiguous(p_c),
                wi, value, pdf, flags, delta)


@jit
def _spread(hit, delta, p_c):
    n, size = delta.shape[0], hit.shape[0]
    of = np.empty(n, np.bool_)
    count = 0
    for h in range(n):
        of[h] = not delta[h] and p_c[h] > 0.0
        count += of[h]
    spread = np.empty(count, np.int64)
    k = 0
    for h in range(n):
        if of[h]:
            spread[k] = h
            k += 1
    count = 0
    for i in range(size):
        if hit[i] < 0 or hit[i] >= n:
            raise IndexError("mix_jit.spread: a pair's hit outside the hits")
        count += of[hit[i]]
    pairs, at = np.empty(count, np.int64), np.empty(count, np.int64)
    k = 0
    for i in range(size):
        if of[hit[i]]:
            pairs[k], at[k] = i, hit[i]
            k += 1
    return spread, pairs, at


def spread(hit, delta, p_c):
    """MixBSDF._spread: (the live hits that took no delta lobe (ascending), every pair of theirs
    (ascending), those pairs' hits).  Refuses (ValueError) unless hit has one axis and delta and p_c
    the same shape (N,); the kernel then refuses (IndexError) a pair's hit outside [0, N)."""
    if not (hit.ndim == 1 and delta.ndim == 1 and p_c.shape == delta.shape):
        raise ValueError(f"mix_jit.spread: hit {hit.shape}, delta {delta.shape}, p_c {p_c.shape}")
    return _spread(contiguous(hit, np.int64), contiguous(delta, np.bool_), contiguous(p_c))


@jit
def _mixture(spread, f_sum, p_sum, value, pdf):
    n = pdf.shape[0]
    for h in spread:
        if not 0 <= h < n:
            raise IndexError("mix_jit.mixture: a hit outside the arrays")
        p = p_sum[h]
        for c in range(3):
            value[c, h] = f_sum[c, h] / p if p > 0.0 else 0.0
        pdf[h] = p


def mixture(spread, f_sum, p_sum, value, pdf):
    """MixBSDF._mixture: value[:, spread] = f_sum / p_sum (0 where p_sum is not > 0), pdf[spread] = p_sum."""
    if f_sum.shape != (3, len(p_sum)) or value.shape != (3, len(pdf)) or len(p_sum) != len(pdf):
        raise ValueError(f"mix_jit.mixture: sums {f_sum.shape}, {p_sum.shape} for {value.shape}")
    _mixture(contiguous(spread, np.int64), contiguous(f_sum), contiguous(p_sum), value, pdf)


@jit
def _fresnel_dielectric(cos, eta):
    """engine/nodes/inputs.py fresnel_dielectric_cos of one hit, then np.clip(f, 0, 1)."""
    c = abs(cos)
    g = eta * eta - 1.0 + c * c
    if not g > 0.0:
        return 1.0
    g = np.sqrt(g)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    f = 0.5 * a * a * (1.0 + b * b)
    if f != f:                                              # np.nan_to_num(f, nan=1.0)
        return 1.0
    if f == np.inf:                                         # ... and +-inf the largest finite floats
        f = FLOAT_MAX
    elif f == -np.inf:
        f = -FLOAT_MAX
    f = f if f > 0.0 else 0.0                               # np.clip(f, 0, 1) (f is not NaN here)
    return f if f < 1.0 else 1.0


@jit
def _view_factor(wo, n, normal, idx, every, fresnel, front, back, out):
    for k in range(out.shape[0]):
        h = k if every else idx[k]
        if h < 0 or h >= wo.shape[1]:
            raise IndexError("mix_jit.view_factor: a hit index outside the hits")
        cos = wo[0, h] * n[0, h] + wo[1, h] * n[1, h] + wo[2, h] * n[2, h]          # engine/core/vec.py dot
        if fresnel:
            behind = wo[0, h] * normal[0, h] + wo[1, h] * normal[1, h] + wo[2, h] * normal[2, h] < 0.0
            out[k] = _fresnel_dielectric(cos, back if behind else front)
        else:
            out[k] = abs(cos)


NO_HITS = np.zeros(0, np.int64)         # view_factor's idx when it reads every hit


def view_factor(wo, n, normal, idx, etas):
    """At the hits idx (None: all) of a ShadingPoint's wo, n and normal (rows (3, N)): with etas =
    (eta in front, eta behind) the Fresnel factor, clipped to [0, 1], of MixBSDF's Fresnel and Layer
    Weight "fresnel" factors (engine/materials/mix.py _factor_input); with etas None |dot(wo, n)|,
    what Layer Weight's "facing" raises to its power (NumPy's: its pow is not libm's)."""
    every = idx is None
    if wo.ndim != 2 or wo.shape[0] != 3 or n.shape != wo.shape or (etas is not None and normal.shape != wo.shape):
        raise ValueError(f"mix_jit.view_factor: wo, n and normal must be rows (3, N) alike, not {wo.shape}, {n.shape}, "
                         f"{normal.shape}")
    out = np.empty(wo.shape[1] if every else len(idx))
    front, back = (1.0, 1.0) if etas is None else (float(etas[0]), float(etas[1]))
    _view_factor(contiguous(wo), contiguous(n), contiguous(normal if etas is not None else n),
                 contiguous(NO_HITS if every else idx, np.int64), every, etas is not None, front, back, out)
    return out



def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    hit = np.array([0, 0, 1])
    prob = np.array([0.25, 0.75, 1.0])
    pick(hit, prob, np.ones(2), np.array([0.5, 0.5]), 1.0 - 1e-12)
    sums(hit, np.ones((3, 3)), np.ones(3), np.ones(3), prob, 2)
    for kept in (None, np.array([True, False, True])):
        by_row(hit, kept, [0, 1])
    table = np.array([[0, 1], [2, -1]])
    placed = place(np.array([0, 1]), np.array([2, 1]), table, table, np.ones((2, 2)), np.ones((3, 3)))
    probabilities(placed[0], placed[3], placed[4], 0.05, 2)
    put(np.zeros((3, 3)), np.zeros(3), np.array([2, 0]), np.ones((3, 2)), np.ones(2))
    from types import SimpleNamespace
    sample = SimpleNamespace(wi=np.ones((3, 2)), value=np.ones((3, 2)), pdf=np.ones(2),
                             flags=np.array([4, 16], np.int8))
    wi, value, pdf = np.zeros((3, 2)), np.zeros((3, 2)), np.zeros(2)
    write_leaf(np.array([0, 1]), np.array([0, 2]), sample, 16, placed[3], np.ones(2), wi, value, pdf,
         np.zeros(2, np.int8), np.zeros(2, np.bool_))
    mixture(spread(placed[0], np.array([False, True]), np.ones(2))[0], value, pdf, value, pdf)
    rows = np.array([[0.0, 0.6, 0.8]] * 3).T.copy()
    for idx in (None, np.array([1])):
        for etas in ((1.45, 1.0 / 1.45), None):
            view_factor(rows, rows, -rows, idx, etas)
