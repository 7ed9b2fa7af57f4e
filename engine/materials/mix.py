"""Mix and Add Shaders as Cycles evaluates them: a material is a weighted list of closures (the
leaves of engine/scene/model.py Mix), each scattered by its own row of the material table.

At a hit, leaf c has the weight w_c, the product of its factors (`leaf_weights`): constants, Fresnel
and Layer Weight nodes of the view direction, image textures at the hit's UV.  As Cycles'
surface_shader_bsdf_sample and surface_shader_bsdf_eval_mis (its kernel/integrator/surface_shader.h):

* `sample` picks leaf c with probability p_c = w_c a_c / sum_k w_k a_k, a_c the leaf's albedo
  estimate (the mean of its colour, at least ALBEDO_FLOOR, so that no leaf that reflects is never
  picked: Cycles' sample_weight is the closure weight's average), and samples it.  A non-delta
  direction is then one sample of the mixture of the non-delta leaves (one-sample MIS over the
  closures): value = sum_c w_c f_c cos / sum_c p_c pdf_c, pdf = sum_c p_c pdf_c.  A delta direction
  (mirror, smooth glass) is the leaf's alone: value = w_c x its value / p_c, pdf = p_c x its pdf.
* `eval` = (sum_c w_c f_c cos, sum_c p_c pdf_c); `pdf` = sum_c p_c pdf_c: light samples and MIS see
  exactly the density `sample` draws from.

Leaves are ordinary materials, appended to the table's material ids (engine/scene/model.py
with_mix_leaves), so every row the table has scatters them, including rows added later; the mix
knows none by name.  A glass leaf crosses the path's medium stack as a glass surface does.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..core.backend import NUMBA
from ..core.vec import dot
from ..scene.model import FRESNEL, LAYER_WEIGHT, PROGRAM, TEXTURE
from .protocol import BSDF, DELTA_LOBE, BSDFFlags, BSDFSample, ShadingPoint
from ..nodes.inputs import fresnel_dielectric_cos   # Cycles' Fresnel of the Fresnel and Layer Weight factors

ALBEDO_FLOOR = 0.05             # a leaf's albedo estimate is at least this (black leaves may reflect)
# Cycles' colour-to-float conversion (linear_rgb_to_gray): luminance of linear Rec.709 (rgb_to_y).
LUMINANCE = np.array([0.2126729, 0.7151522, 0.0721750])
DEAD = BSDFFlags.DIFFUSE | BSDFFlags.REFLECTION     # the flags of a hit whose weights are all 0
U_MAX = 1.0 - 1e-12             # the largest uniform the pick passes on
READ = (FRESNEL, LAYER_WEIGHT, TEXTURE, PROGRAM)   # factors read at the hits (the other kind: constants)


def _ids_in(ids: np.ndarray) -> np.ndarray:
    """np.unique of non-negative integer ids (material ids, table rows): the same sorted values,
    counted instead of sorted."""
    return np.flatnonzero(np.bincount(ids)) if len(ids) else np.empty(0, dtype=np.int64)


def factor_value(factor, si: ShadingPoint) -> np.ndarray:
    """The factor (engine/scene/model.py MixFactor) at the hits `si`, clamped to [0, 1] as a Mix
    Shader's Fac (constants: as given), inverted for a Mix Shader's first input."""
    if factor.kind not in READ:
        return np.full(len(si), factor.constant())
    f = _factor_input(factor, si)
    return 1.0 - f if factor.invert else f


def _facing(si: ShadingPoint) -> tuple[np.ndarray, np.ndarray]:
    """What the Fresnel and Layer Weight factors read of the hits: (cos, backfacing) (N,) each."""
    cos = dot(si.wo, si.n)                                   # Cycles: dot(sd->wi, N), N the shading normal
    return cos, dot(si.wo, si.normal) < 0.0                  # the viewer inside the surface


def _etas(factor):
    """(eta in front, eta behind) of a Fresnel factor (its svm_node_fresnel) or a Layer Weight's
    "fresnel" (its svm_node_layer_weight): the IOR ratio its fresnel_dielectric_cos reads; None for
    Layer Weight's "facing"."""
    if factor.kind == FRESNEL:
        eta = max(factor.ior, 1e-5)
        return eta, 1.0 / eta
    if factor.output == "fresnel":
        eta = max(1.0 - factor.blend, 1e-5)
        return 1.0 / eta, eta
    return None


def _layer_facing(abs_cos: np.ndarray, blend: float) -> np.ndarray:
    """Layer Weight's "facing" of |dot(wo, n)| (before the clip)."""
    f = abs_cos
    if blend != 0.5:
        blend = min(max(blend, 0.0), 1.0 - 1e-5)
        f = f ** (2.0 * blend if blend < 0.5 else 0.5 / (1.0 - blend))
    return 1.0 - f


def _factor_input(factor, si: ShadingPoint, facing=None) -> np.ndarray:
    """A factor read at the hits (not a constant), clamped to [0, 1], before its invert; `facing`:
    _facing(si) when known (si is then not read: None will do)."""
    if factor.kind == FRESNEL or factor.kind == LAYER_WEIGHT:
        cos, backfacing = _facing(si) if facing is None else facing
        etas = _etas(factor)
        if etas is not None:
            f = fresnel_dielectric_cos(cos, np.where(backfacing, etas[1], etas[0]))
        else:
            f = _layer_facing(np.abs(cos), factor.blend)
    elif factor.kind == TEXTURE:
        if si.lookup is None:
            f = np.full(len(si), float(factor.value))
        else:
            f = si.lookup.factor(factor.texture, factor.value)
    elif factor.kind == PROGRAM:                             # a node program (engine/nodes/evaluator.py)
        f = np.full(len(si), float(factor.value)) if si.lookup is None else si.lookup.program(factor.program)
    return np.clip(f, 0.0, 1.0)


def _same_input(a, b) -> bool:
    """Whether factors a and b read the same value (they may differ in `invert` alone: the two
    leaves of a Mix Shader, Fac and 1 - Fac)."""
    return a.kind in READ and replace(a, invert=b.invert) == b


def _first_readers(leaves) -> list:
    """For each leaf, for each of its factors the first factor of the material's leaves that reads
    the same value (itself if none before it does): `_pairs` reads each value once."""
    seen, firsts = [], []
    for leaf in leaves:
        mine = []
        for factor in leaf.factors:
            first = next((known for known in seen if _same_input(known, factor)), None)
            if first is None:
                seen.append(factor)
            mine.append(factor if first is None else first)
        firsts.append(mine)
    return firsts


class _Leaves:
    """The leaves of some (hit, leaf) pairs by table row: for row r a ShadingPoint of every pair of
    a span with that row (`rows[r]`, a span's view for engine/materials/protocol.py: a take of it
    reads its memo), and each pair's place in it (`slot`).  A leaf BSDF's per-hit values (frames,
    alphas, compensation: its ShadingPoint.memo) are then computed once per bounce for the light
    samples' eval, the sample and the sample's mixture eval, not once per call.  `media`: the pairs'
    medium stacks as they were when the call began (a leaf's sample updates the paths' own), or None;
    a leaf's memo reads the stacks `rows[r]` was made with (the bounce's first call: before any of its
    leaves crossed a surface, as the calls' own stacks are for every pair they evaluate).  `whole`:
    the pairs are the span's own, in order (a take of all), so that every pair of a row is that row's
    view itself, which `at` then takes whole (no gathers)."""

    def __init__(self, rows, slot, media=None, whole=False):
        self.rows, self.slot, self.media, self.whole = rows, slot, media, whole

    @classmethod
    def of(cls, si: ShadingPoint, hit, groups, leaf, color):
        """The pairs (hit, leaf material, leaf colour) of the hits `si` (without `media`), grouped by
        row (MixBSDF._by_row)."""
        rows, slot = {}, np.empty(len(hit), dtype=np.int64)
        for r, sel in groups:
            slot[sel] = np.arange(len(sel))
            view = si.take(hit.take(sel))
            view.color, view.material = color.take(sel, axis=1), leaf.take(sel)   # a ShadingPoint of its own
            object.__setattr__(view, "_shared", True)                           # ... whose takes read its memo
            rows[int(r)] = view
        return cls(rows, slot)

    def take(self, pairs, hit: np.ndarray, media) -> "_Leaves":
        """The pairs `pairs` of these (None: all), now at the hits `hit` (per pair) of the medium
        stacks `media` (or None): their stacks copied from those now, as a take of the hits would."""
        stacks = None if media is None else type(media)(media.media.take(hit, axis=0), media.depth.take(hit))
        if pairs is None:
            return _Leaves(self.rows, self.slot, stacks, whole=True)
        return _Leaves(self.rows, self.slot.take(pairs), stacks)

    def at(self, r: int, pairs: np.ndarray, media=None) -> ShadingPoint:
        """The row-r leaves of pairs `pairs` (all of row r, ascending), with the medium stacks `media`
        (default: these pairs' own), set without starting the take's memo afresh
        (ShadingPoint.__setattr__)."""
        every = self.whole and len(pairs) == len(self.rows[r])     # then the row's pairs in order
        view = self.rows[r].take(None if every else self.slot.take(pairs))
        if media is None and self.media is not None:
            media = type(self.media)(self.media.media.take(pairs, axis=0), self.media.depth.take(pairs))
        if media is not None:
            object.__setattr__(view, "media", media)
        return view


class MixBSDF(BSDF):
    """The leaves of every mix material, scattered through the material table's rows."""
    flags = BSDFFlags.NONE          # per instance: the union of its leaves' rows (bind)

    def __init__(self, materials, settings):
        self.materials = materials
        self.closures = {}              # material id -> [(leaf material id, row, factors, first readers)] (bind)
        self.rows = []                  # the rows of every material's leaves, ascending (bind)
        self.compiled = None

    def use_backend(self, backends: dict) -> None:
        """The pairs' bookkeeping compiled (engine/materials/mix_jit.py, the same numbers) when the
        render runs the mix on numba: their placing (_placed), pick probabilities (_probabilities), grouping
        by row (_by_row), the Fresnel and Layer Weight factors' view (_view_factor), a row's eval scatter
        (_eval_pairs), the per-hit sums (_sums), the pick (_pick) and the sample's writes (_write_leaf,
        _spread, _mixture); the leaves are the material table's rows (their own choice)."""
        if backends.get("mix") == NUMBA:
            from . import mix_jit
            self.compiled = mix_jit
        else:
            self.compiled = None

    def bind(self, table, leaf_ids) -> None:
        """Take the leaves' rows from the material table (engine/materials/table.py) and the leaf
        material ids of each material (engine/scene/model.py with_mix_leaves)."""
        self.table = table
        flags = BSDFFlags.NONE
        self.leaf_count = np.zeros(len(leaf_ids), np.int64)     # leaves per material (its pairs per hit)
        for m, ids in enumerate(leaf_ids):
            if not ids:
                continue
            self.leaf_count[m] = len(ids)
            leaves = self.materials[m].mix.leaves
            self.closures[m] = [(leaf_id, int(table.kind[leaf_id]), leaf.factors, firsts)
                                for leaf_id, leaf, firsts in zip(ids, leaves, _first_readers(leaves))]
            for leaf_id, row, _, _ in self.closures[m]:
                flags |= table.bsdfs[row].flags
        self.flags = flags
        self.rows = sorted({row for closures in self.closures.values() for _, row, _, _ in closures})   # the leaves' rows
        self.leaf_ids = np.array([leaf_id for closures in self.closures.values() for leaf_id, _, _, _ in closures],
                                 np.int64)
        self._colour_reads = (None, None)                   # (the lookups' textures, whether leaf colours read them)
        # For mix_jit.place: material m's j-th leaf and its row (-1 past its leaves)
        self.leaf_table = np.full((len(leaf_ids), max(1, int(self.leaf_count.max(initial=0)))), -1, np.int64)
        self.row_table = self.leaf_table.copy()
        for m, closures in self.closures.items():
            for j, (leaf_id, row, _, _) in enumerate(closures):
                self.leaf_table[m, j], self.row_table[m, j] = leaf_id, row

    # -- the closures at some hits ----------------------------------------------------------------
    def _pairs(self, si: ShadingPoint):
        """Every (hit, leaf) pair of the hits, hit-major (a hit's pairs follow each other, its leaves in
        the material's order): (hit (P,), row (P,), weight (P,), probability (P,), total weight x albedo
        per hit (N,), the leaves of the pairs (_Leaves))."""
        n = len(si)
        hit, leaf, row, weight, color = self._placed(si)
        if si.lookup is not None and self._colours_read(si.lookup):
            color = si.lookup.take(hit).color(color, leaf)
        leaves = _Leaves.of(si, hit, self._by_row(row), leaf, color)
        prob, total = self._probabilities(hit, weight, color, n)
        return hit, row, weight, prob, total, leaves

    def _colours_read(self, lookup) -> bool:
        """Whether the hits' lookups (engine/materials/textures.py HitLookup) may change a leaf's colour:
        some leaf has an image texture or a node program on it.  Otherwise HitTextures.color gives back
        the colours it is given (the same array), and its per-pair gathers are left out."""
        textures = lookup.textures
        if self._colour_reads[0] is not textures:           # once per scene's lookups
            programs = (textures.attributes is not None
                        and textures.textures.has_program["color"].take(self.leaf_ids).any())
            self._colour_reads = (textures, bool(programs or textures.has_color.take(self.leaf_ids).any()))
        return self._colour_reads[1]

    def _material_weights(self, si: ShadingPoint):
        """(material m, its hits idx in si, its leaves' weights there (_weights)) for each material of si."""
        for m in _ids_in(si.material):
            idx = np.flatnonzero(si.material == m)
            yield int(m), idx, self._weights(si, int(m), idx)

    def _placed(self, si: ShadingPoint):
        """The pairs of _pairs before the colour lookups and the probabilities: (hit, leaf material id,
        row, weight (P,) each, the leaves' table colours (3, P)).  Each hit's pairs start at the cumulative
        sum of its material's leaf count: every leaf's pairs are written at their hit-major places."""
        if self.compiled is not None:                       # mix_jit.place: the same pairs in one pass
            weights = np.empty((self.leaf_table.shape[1], len(si)))
            for m, idx, leaf_weights in self._material_weights(si):
                for j, w in enumerate(leaf_weights):
                    weights[j, idx] = w
            return self.compiled.place(si.material, self.leaf_count, self.leaf_table, self.row_table, weights,
                                       self.table.color)
        count = self.leaf_count.take(si.material)          # pairs per hit
        hit = np.repeat(np.arange(len(si)), count)
        start = np.cumsum(count) - count                    # each hit's first pair
        leaf, row, weight = np.empty(len(hit), np.int64), np.empty(len(hit), np.int64), np.empty(len(hit))
        for m, idx, leaf_weights in self._material_weights(si):
            first = start.take(idx)
            for j, ((leaf_id, r, _, _), w) in enumerate(zip(self.closures[m], leaf_weights)):
                pairs = first + j
                leaf[pairs], row[pairs], weight[pairs] = leaf_id, r, w
        return hit, leaf, row, weight, self.table.color.take(leaf, axis=1)

    def _probabilities(self, hit, weight, color, n):
        """(each pair's pick probability p_c (P,), each hit's total weight x albedo (n,)): the albedo the
        leaf colour's mean, at least ALBEDO_FLOOR."""
        if self.compiled is not None:                       # mix_jit.probabilities: the same numbers
            return self.compiled.probabilities(hit, weight, color, ALBEDO_FLOOR, n)
        albedo = (color[0] + color[1] + color[2]) / 3.0    # color.mean(axis=0), the same sums
        rate = weight * np.maximum(albedo, ALBEDO_FLOOR)
        total = np.bincount(hit, weights=rate, minlength=n)
        of_hit = total.take(hit)
        with np.errstate(divide="ignore", invalid="ignore"):
            prob = np.where(of_hit > 0.0, rate / of_hit, 0.0)
        return prob, total

    def _weights(self, si: ShadingPoint, m: int, idx: np.ndarray) -> list:
        """The weight (len(idx),) of each leaf of material m at the hits `idx` of si, each value a
        factor reads computed once for the leaves that share it; si taken at idx only for the factors
        that read more than the hits' view (_view_factor)."""
        every = len(idx) == len(si)
        at = si if every else None                              # si.take(idx) once a factor needs it
        read, weights = {}, []
        for _, _, factors, firsts in self.closures[m]:
            w = None                                            # the product from 1: 1 x the first factor is it
            for factor, first in zip(factors, firsts):
                if factor.kind not in READ:
                    c = float(factor.constant())
                    w = np.full(len(idx), c) if w is None else w * c
                    continue
                if id(first) not in read:
                    if first.kind == FRESNEL or first.kind == LAYER_WEIGHT:
                        read[id(first)] = self._view_factor(first, si, idx, every)
                    else:
                        at = si.take(idx) if at is None else at
                        read[id(first)] = _factor_input(first, at)
                f = read[id(first)]
                f = 1.0 - f if factor.invert else f
                w = f if w is None else w * f
            weights.append(np.ones(len(idx)) if w is None else w)
        return weights

    def _view_factor(self, factor, si: ShadingPoint, idx: np.ndarray, every: bool) -> np.ndarray:
        """_factor_input of a Fresnel or Layer Weight factor at the hits idx of si (`every`: all of
        them).  Compiled: the hits' view and the Fresnel in mix_jit.view_factor's loop over idx (no takes;
        Layer Weight's "facing" then takes its power from NumPy: the same numbers).  NumPy: the view
        (_facing) once for every hit of si (its memo), then taken."""
        if self.compiled is not None:
            etas = _etas(factor)
            f = self.compiled.view_factor(si.wo, si.n, si.normal, None if every else idx, etas)
            return f if etas is not None else np.clip(_layer_facing(f, factor.blend), 0.0, 1.0)
        facing = si.memo(("mix", "facing"), _facing)
        if every:
            return _factor_input(factor, si, facing)
        return _factor_input(factor, None, (facing[0].take(idx), facing[1].take(idx)))

    def _pairs_at(self, si: ShadingPoint):
        """_pairs of the hits `si`, computed once per span (ShadingPoint.memo_at: the light samples'
        eval and the sample of a bounce read the same factors, texture lookups and leaves) and
        gathered for a take of it: the taken hits' pairs in the same order, so every per-hit sum is
        the same.  The leaves' medium stacks are copied from si's now, as a take of si would.  Hits of
        no span (tests, which may set a field of them between calls) compute their own each time."""
        if not (si._shared or si._source is not None):
            hit, row, weight, prob, total, leaves = self._pairs(si)
            return hit, row, weight, prob, total, leaves.take(None, hit, si.media)
        (hit, row, weight, prob, total, leaves, start, count), index = si.memo_at((self, "pairs"), self._span_pairs)
        if index is not None:
            c = count.take(index)
            hit = np.repeat(np.arange(len(index)), c)
            pairs = np.repeat(start.take(index) - (np.cumsum(c) - c), c) + np.arange(len(hit))
            row, weight, prob = row.take(pairs), weight.take(pairs), prob.take(pairs)
            return hit, row, weight, prob, total.take(index), leaves.take(pairs, hit, si.media)
        return hit, row, weight, prob, total, leaves.take(None, hit, si.media)

    def _span_pairs(self, si: ShadingPoint):
        """_pairs and, per hit, where its pairs start and how many it has (not per-hit arrays: read
        through _pairs_at only)."""
        hit, row, weight, prob, total, leaves = self._pairs(si)
        count = self.leaf_count.take(si.material)          # each hit's pairs: its material's leaves
        return hit, row, weight, prob, total, leaves, np.cumsum(count) - count, count

    def _by_row(self, rows: np.ndarray, keep: np.ndarray | None = None) -> list:
        """[(r, the places (ascending) where `rows` is r and `keep` is True)] for the leaves' rows r
        (ascending) that have any."""
        if self.compiled is not None:                       # mix_jit.by_row: one counting pass, the same places
            return self.compiled.by_row(rows, keep, self.rows)
        groups = []
        for r in self.rows:
            k = np.flatnonzero(rows == r if keep is None else (rows == r) & keep)
            if len(k):
                groups.append((r, k))
        return groups

    def _sums(self, hit, f_cos, weight, pdf, prob, n):
        """Per-hit sums over the pairs (hit (P,)) of f_cos x weight (3, n) and of pdf x prob (n,)."""
        if self.compiled is not None:                       # mix_jit.sums: the same sums in the same order
            return self.compiled.sums(hit, f_cos, weight, pdf, prob, n)
        f_sum = np.stack([np.bincount(hit, weights=r, minlength=n) for r in f_cos * weight])
        return f_sum, np.bincount(hit, weights=pdf * prob, minlength=n)

    def _pick(self, hit, prob, total, u_lobe):
        """One pair per hit by u_lobe over its pairs' probabilities (hit-major: the pairs of a hit
        follow each other), u_lobe rescaled for the leaf: (chosen pair, its probability p_c, the
        leaf's uniform) (N,) each."""
        if self.compiled is not None:                       # mix_jit.pick: the same numbers
            return self.compiled.pick(hit, prob, total, u_lobe, U_MAX)
        start = np.searchsorted(hit, np.arange(len(total)))
        stop = np.append(start[1:], len(hit))
        cum = np.cumsum(prob)
        base = cum.take(np.minimum(start, len(hit) - 1)) - prob.take(np.minimum(start, len(hit) - 1))
        target = base + np.minimum(u_lobe, U_MAX) * np.where(total > 0.0, 1.0, 0.0)
        chosen = np.clip(np.searchsorted(cum, target, side="right"), start, stop - 1)
        p_c = prob.take(chosen)
        with np.errstate(divide="ignore", invalid="ignore"):
            u_leaf = np.clip((target - (cum.take(chosen) - p_c)) / p_c, 0.0, U_MAX)
        return chosen, p_c, np.where(p_c > 0.0, u_leaf, 0.0)

    def _eval_pairs(self, row, leaves, wi, hit, only=None):
        """(f cos (3, P), pdf (P,)) of the leaves at the directions wi (3, N) of their hits `hit` (per
        pair); `only`: the pairs to evaluate, `hit` then theirs alone and the results theirs alone
        (3, len(only)), (len(only),): no full-length temporaries where a sample's mixture needs some
        hits' pairs.  Each row's directions are gathered from wi at once (no per-pair copy of wi)."""
        f_cos, pdf = np.zeros((3, len(hit))), np.zeros(len(hit))
        for r, k in self._by_row(row if only is None else row.take(only)):   # k: places in the results
            if not self.table.non_delta[r]:
                continue                                    # delta leaves: no given direction meets them
            sel = k if only is None else only.take(k)       # the pairs themselves
            f, p = self.table.bsdfs[r].eval(leaves.at(r, sel), wi.take(hit.take(k), axis=1))
            if self.compiled is not None:                   # mix_jit.put: the same copies in one loop
                self.compiled.put(f_cos, pdf, k, f, p)
            else:
                f_cos[:, k], pdf[k] = f, p
        return f_cos, pdf

    def eval(self, si: ShadingPoint, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = len(si)
        hit, row, weight, prob, _, leaves = self._pairs_at(si)
        f_cos, pdf = self._eval_pairs(row, leaves, wi, hit)
        return self._sums(hit, f_cos, weight, pdf, prob, n)

    def pdf(self, si: ShadingPoint, wi: np.ndarray) -> np.ndarray:
        return self.eval(si, wi)[1]

    def sample(self, si: ShadingPoint, u_lobe: np.ndarray, u) -> BSDFSample:
        n = len(si)
        hit, row, weight, prob, total, leaves = self._pairs_at(si)
        chosen, p_c, u_leaf = self._pick(hit, prob, total, u_lobe)
        wi, value = np.zeros((3, n)), np.zeros((3, n))
        pdf, flags = np.zeros(n), np.full(n, DEAD, dtype=np.int8)
        wi[:] = si.n
        delta = np.zeros(n, dtype=bool)
        for r, mine in self._by_row(row.take(chosen), p_c > 0.0):  # the live hits that picked a row-r leaf
            pairs = chosen.take(mine)
            media = None                                    # glass leaves cross the paths' media
            if si.media is not None:
                media = type(si.media)(si.media.media[mine], si.media.depth[mine])
            at = leaves.at(int(r), pairs, media)
            bsdf = self.table.bsdfs[r]
            uv = None if (u is None or not self.table.non_delta[r]) else (u[0].take(mine), u[1].take(mine))
            s = bsdf.sample(at, u_leaf.take(mine), uv)
            if si.media is not None:
                si.media.media[mine], si.media.depth[mine] = at.media.media, at.media.depth
            self._write_leaf(mine, pairs, s, weight, p_c, wi, value, pdf, flags, delta)
        # Non-delta samples: the mixture of every non-delta leaf of the hit at wi.
        spread, pairs, at = self._spread(hit, delta, p_c)
        if len(spread):
            f_cos, p = self._eval_pairs(row, leaves, wi, at, only=pairs)
            f_sum, p_sum = self._sums(at, f_cos, weight.take(pairs), p, prob.take(pairs), n)
            self._mixture(spread, f_sum, p_sum, value, pdf)
        return BSDFSample(wi, value, pdf, flags)

    def _write_leaf(self, mine, pairs, s: BSDFSample, weight, p_c, wi, value, pdf, flags, delta) -> None:
        """Write the leaf samples `s` of the hits `mine` (their chosen pairs `pairs`) into the sample's
        arrays: wi, flags and whether the lobe is a delta of each; where it is, the leaf's own value x
        weight / p_c and pdf x p_c (the other hits' value and pdf: the mixture's, _mixture)."""
        if self.compiled is not None:                       # mix_jit.write_leaf: the same numbers in one loop
            self.compiled.write_leaf(mine, pairs, s, DELTA_LOBE, weight, p_c, wi, value, pdf, flags, delta)
            return
        wi[:, mine], flags[mine] = s.wi, s.flags
        is_delta = (s.flags & DELTA_LOBE) != 0
        delta[mine] = is_delta
        d = mine[is_delta]
        w_over_p = weight.take(pairs[is_delta]) / p_c.take(d)
        value[:, d] = s.value[:, is_delta] * w_over_p
        pdf[d] = p_c.take(d) * s.pdf[is_delta]

    def _spread(self, hit, delta, p_c):
        """(the live hits whose leaf took no delta lobe, every pair of those hits (their sums whole),
        those pairs' hits), ascending."""
        if self.compiled is not None:                       # mix_jit.spread: the same places
            return self.compiled.spread(hit, delta, p_c)
        spread = np.flatnonzero(~delta & (p_c > 0.0))
        of = np.zeros(len(delta), dtype=bool)
        of[spread] = True
        pairs = np.flatnonzero(of.take(hit))
        return spread, pairs, hit.take(pairs)

    def _mixture(self, spread, f_sum, p_sum, value, pdf) -> None:
        """value, pdf at the hits `spread`: the mixture's sums f_sum / p_sum (0 where p_sum is not > 0), p_sum."""
        if self.compiled is not None:                       # mix_jit.mixture: the same quotients
            self.compiled.mixture(spread, f_sum, p_sum, value, pdf)
            return
        f_sum, p_sum = f_sum.take(spread, axis=1), p_sum.take(spread)
        with np.errstate(divide="ignore", invalid="ignore"):
            value[:, spread] = np.where(p_sum > 0.0, f_sum / p_sum, 0.0)
        pdf[spread] = p_sum
