"""The compiled pair bookkeeping of the Mix Shader (engine/materials/mix_jit.py) against the NumPy path
of engine/materials/mix.py: the pick of one pair per hit (probabilities with zeros, hits whose weights
are all 0, uniforms at 0, at 1 and on a cumulative sum's value) and the per-hit sums, bit for bit; a
mix's eval and sample on both backends the same.  Controls: one ulp of one probability, and the sums
taken in another order, are told apart."""
import numpy as np
import pytest

from engine.materials.media import MediumStack
from engine.materials.mix import ALBEDO_FLOOR, U_MAX
from engine.materials.protocol import ShadingPoint
from engine.materials.table import KIND_CODE, MaterialTable
from engine import RenderSettings
from engine.scene.model import MIX, MixFactor
from tests.backend_capture import require_compiled
from tests.materials.test_mix import MIXES, random_hits

TWIN = "engine.materials.mix_jit"       # imported by use_backend, not here: numba may be missing


def mix_pair():
    """(NumPy's MixBSDF, the compiled one) of the test mixes."""
    require_compiled()
    materials = [MIXES[k] for k in ("diffuse+glossy", "diffuse+glass", "fresnel diffuse+glossy", "layer weight",
                                    "glossy+mirror")]
    settings = RenderSettings(fresnel="exact")
    numpy_bsdf = MaterialTable(materials, settings).bsdfs[KIND_CODE[MIX]]
    compiled = MaterialTable(materials, settings).bsdfs[KIND_CODE[MIX]]
    compiled.use_backend({"mix": "numba"})
    assert numpy_bsdf.compiled is None and compiled.compiled is not None
    return numpy_bsdf, compiled, len(materials)


def random_pairs(rng, n=3000):
    """Hit-major pairs: 1-3 per hit, probabilities per hit summing to 1 (some 0, some hits all 0)."""
    count = rng.integers(1, 4, n)
    hit = np.repeat(np.arange(n), count)
    rate = rng.random(len(hit)) * (rng.random(len(hit)) > 0.2)
    rate[np.isin(hit, rng.choice(n, n // 20, replace=False))] = 0.0
    total = np.bincount(hit, weights=rate, minlength=n)
    with np.errstate(divide="ignore", invalid="ignore"):
        prob = np.where(total.take(hit) > 0.0, rate / total.take(hit), 0.0)
    u = rng.random(n)
    u[:50], u[50:100] = 0.0, 1.0                                 # the ends
    cum = np.cumsum(prob)                                        # on a cumulative sum: base + u = cum
    first = np.searchsorted(hit, np.arange(n))
    u[100:200] = (cum.take(first[100:200]) - (cum.take(first[100:200]) - prob.take(first[100:200])))
    return hit, prob, total, u


def test_the_pick_is_numpys():
    numpy_bsdf, compiled, _ = mix_pair()
    rng = np.random.default_rng(5)
    for _ in range(3):
        hit, prob, total, u = random_pairs(rng)
        a = numpy_bsdf._pick(hit, prob, total, u)
        b = compiled._pick(hit, prob, total, u)
        assert all(np.array_equal(x, y) for x, y in zip(a, b))
        assert (a[1] == 0.0).any() and (a[2] > 0.0).any()
    # control: one ulp of one picked pair's probability is told apart
    k = int(a[0][np.flatnonzero(a[1] > 0.0)[0]])
    nudged = prob.copy()
    nudged[k] = np.nextafter(nudged[k], 2.0)
    c = compiled._pick(hit, nudged, total, u)
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


def test_the_pick_is_numpys_on_odd_tables_and_uniforms():
    """NaN, -0 and inf uniforms on a sorted table (the stepping through a hit's pairs), and tables with
    a NaN probability (no longer sorted: the binary search of the whole table, NumPy's)."""
    numpy_bsdf, compiled, _ = mix_pair()
    rng = np.random.default_rng(17)
    hit, prob, total, u = random_pairs(rng, 400)
    u[200:210], u[210:220], u[220:230], u[230:240] = np.nan, -0.0, np.inf, -np.inf
    tables = [prob]
    for k in (0, 123, len(prob) - 1):                            # a NaN first, inside, last
        bad = prob.copy()
        bad[k] = np.nan
        tables.append(bad)
    for table in tables:
        with np.errstate(invalid="ignore"):
            a = numpy_bsdf._pick(hit, table, total, u)
        b = compiled._pick(hit, table, total, u)
        assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))
    # ties: targets exactly on a hit's first cumulative sum (searchsorted side "right" counts it: the
    # second pair) ...
    hit, prob = np.repeat(np.arange(50), 2), np.full(100, 0.5)
    tie, total = np.full(50, 0.5), np.ones(50)
    cum = np.cumsum(prob)
    assert np.array_equal(cum[0::2] - prob[0::2] + tie, cum[0::2])
    a, b = numpy_bsdf._pick(hit, prob, total, tie), compiled._pick(hit, prob, total, tie)
    assert all(np.array_equal(x, y) for x, y in zip(a, b)) and (a[0] % 2 == 1).all()
    # control: ... and one ulp below them the first pair (a step comparing with < would pick it at the tie)
    lower = np.nextafter(tie, 0.0)
    under = cum[0::2] - prob[0::2] + lower < cum[0::2]            # the hits whose target is now below
    below = compiled._pick(hit, prob, total, lower)
    assert under.sum() >= 1 and (below[0][under] % 2 == 0).all()


def groups_equal(a, b) -> bool:
    return len(a) == len(b) and all(r == q and k.dtype == j.dtype and np.array_equal(k, j)
                                    for (r, k), (q, j) in zip(a, b))


def test_the_rows_grouping_is_numpys():
    """The pairs grouped by row (MixBSDF._by_row) on captured-like rows (the mixes' own) and odd ones:
    empty, rows no leaf has (ignored: above, between and below the leaves' rows), keep masks none,
    all False and random."""
    numpy_bsdf, compiled, _ = mix_pair()
    assert numpy_bsdf.rows == compiled.rows and len(numpy_bsdf.rows) >= 3
    rng = np.random.default_rng(23)
    codes = numpy_bsdf.rows
    cases = [np.zeros(0, np.int64), rng.choice(codes, 5000),
             rng.integers(-2, max(codes) + 3, 5000), np.full(100, codes[-1])]
    for rows in cases:
        for keep in (None, np.zeros(len(rows), bool), rng.random(len(rows)) < 0.6):
            a, b = numpy_bsdf._by_row(rows, keep), compiled._by_row(rows, keep)
            assert groups_equal(a, b)
    assert len(numpy_bsdf._by_row(cases[1])) == len(codes)
    # control: one pair moved to another row is told apart
    moved = cases[1].copy()
    moved[1234] = codes[0] if moved[1234] != codes[0] else codes[1]
    assert not groups_equal(numpy_bsdf._by_row(cases[1]), compiled._by_row(moved))


def test_the_sums_are_bincounts_in_the_pairs_order():
    numpy_bsdf, compiled, _ = mix_pair()
    rng = np.random.default_rng(9)
    hit, prob, _, _ = random_pairs(rng)
    n = hit[-1] + 1
    f_cos, weight, pdf = rng.random((3, len(hit))) * 3.0, rng.random(len(hit)), rng.random(len(hit)) * 7.0
    a = numpy_bsdf._sums(hit, f_cos, weight, pdf, prob, n)
    b = compiled._sums(hit, f_cos, weight, pdf, prob, n)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    # control: the same pairs summed last to first differ in the last bit somewhere
    back = slice(None, None, -1)
    c = compiled._sums(hit[back], f_cos[:, back], weight[back], pdf[back], prob[back], n)
    assert not (np.array_equal(a[0], c[0]) and np.array_equal(a[1], c[1]))


def test_eval_and_sample_are_the_same_on_both_backends():
    numpy_bsdf, compiled, kinds = mix_pair()
    n, rng = 2000, np.random.default_rng(31)
    normal, wo, facing, material, wi, u_lobe, u, idx = random_hits(rng, n, kinds)
    out = []
    for bsdf in (numpy_bsdf, compiled):
        si = ShadingPoint(wo.copy(), facing.copy(), facing.copy(), normal.copy(), np.ones((3, n)), material.copy())
        si.media = MediumStack.empty(n)
        span = si[0:n]
        f, p = bsdf.eval(span.take(idx), wi.take(idx, axis=1))
        s = bsdf.sample(span, u_lobe, u)
        out.append((f, p, s.wi, s.value, s.pdf, s.flags, si.media.media, si.media.depth))
    assert (out[0][1] > 0).sum() > len(idx) // 4
    for x, y in zip(*out):
        assert np.array_equal(x, y)


@pytest.mark.parametrize("u_max", [U_MAX])
def test_warm_up_covers_the_kernels(u_max):
    require_compiled()
    import importlib
    twin = importlib.import_module(TWIN)
    twin.warm_up()
    chosen, p_c, u_leaf = twin.pick(np.array([0, 1]), np.array([1.0, 1.0]), np.ones(2), np.array([1.0, 0.0]), u_max)
    assert list(chosen) == [0, 1] and u_leaf[0] == u_max and u_leaf[1] == 0.0


# -- the Fresnel and Layer Weight factors (mix_jit.view_factor, MixBSDF._view_factor) ----------------------------
VIEW_FACTORS = ([MixFactor("fresnel", ior=ior) for ior in (1.45, 1.0, 0.5, 1e-9, 40.0)]
                + [MixFactor("layer_weight", blend=b, output="fresnel") for b in (0.0, 0.3, 0.5, 0.99, 1.0)]
                + [MixFactor("layer_weight", blend=b, output="facing") for b in (0.0, 0.25, 0.3, 0.5, 0.75, 0.4000000059604645, 1.0)])


def both_views(factor, si, idx):
    """(NumPy's, the compiled) _view_factor of `factor` at the hits idx of si (all when idx has them)."""
    numpy_bsdf, compiled, _ = mix_pair()
    every = len(idx) == len(si)
    with np.errstate(all="ignore"):
        return numpy_bsdf._view_factor(factor, si, idx, every), compiled._view_factor(factor, si, idx, every)


def edge_hits(n=600, seed=3):
    """Hits whose wo and n meet at every angle, grazing (cos +-1, 0, -0.0), from behind (normal opposite
    wo) and with NaN, inf and zero components."""
    rng = np.random.default_rng(seed)
    normal = rng.normal(size=(3, n))
    normal /= np.linalg.norm(normal, axis=0)
    wo = rng.normal(size=(3, n))
    wo /= np.linalg.norm(wo, axis=0)
    shading = np.where(rng.random(n) < 0.5, normal, -normal) + 0.1 * rng.normal(size=(3, n))
    wo[:, 0], shading[:, 0] = (1.0, 0.0, 0.0), (1.0, 0.0, 0.0)           # cos 1
    wo[:, 1], shading[:, 1] = (1.0, 0.0, 0.0), (-1.0, 0.0, 0.0)          # cos -1
    wo[:, 2], shading[:, 2] = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)           # cos 0
    wo[:, 9], shading[:, 9], normal[:, 9] = (1.0, 0.0, 0.0), (0.6, 0.8, 0.0), (0.0, 0.0, 1.0)   # on the side
    wo[:, 3], shading[:, 3] = (-0.0, 0.0, 1.0), (1.0, 0.0, -0.0)         # cos -0.0
    wo[0, 4], shading[1, 5], normal[2, 6], wo[:, 7] = np.nan, np.inf, np.nan, 0.0
    wo[:, 8], shading[:, 8] = (1e200, 0.0, 0.0), (1e200, 0.0, 0.0)       # cos inf
    si = ShadingPoint(wo, shading, shading, normal, np.ones((3, n)), np.zeros(n, np.int64))
    return si


def same_bits(a, b):
    return a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True) and np.array_equal(np.signbit(a), np.signbit(b))


def test_the_view_factors_are_numpys_on_edge_hits():
    si = edge_hits()
    some = np.sort(np.random.default_rng(4).choice(len(si), 250, replace=False))
    for factor in VIEW_FACTORS:
        for idx in (np.arange(len(si)), some, np.zeros(0, np.int64)):
            a, b = both_views(factor, si, idx)
            assert same_bits(a, b), (factor, len(idx))
    a, _ = both_views(MixFactor("fresnel", ior=1.45), si, np.arange(len(si)))
    assert (a == 1.0).any() and ((a > 0.0) & (a < 1.0)).any()       # beyond the critical angle, and not


def test_the_view_factors_of_a_render_are_numpys():
    """Every Fresnel / Layer Weight factor the mixes read in a NumPy render of a floor whose two
    triangles have a Fresnel mix and a Layer Weight mix (the hits and each material's indices as the
    render passes them), compiled: the same numbers."""
    from engine import render
    from engine.materials.mix import MixBSDF
    from tests.materials.test_mix import textured_floor_scene
    import importlib
    twin = importlib.import_module(TWIN)
    original, seen = MixBSDF._view_factor, []

    def recording(self, factor, si, idx, every):
        reference = original(self, factor, si, idx, every)
        self.compiled = twin
        try:
            seen.append((reference, original(self, factor, si, idx, every), every))
        finally:
            self.compiled = None
        return reference
    scene = textured_floor_scene(MIXES["fresnel diffuse+glossy"])      # its triangles: Fresnel, Layer Weight
    scene.materials.append(MIXES["layer weight"])
    scene.meshes[0].material_ids = np.array([0, 2])
    MixBSDF._view_factor = recording
    try:
        render(scene, RenderSettings(samples=16, seed=2, threads=1, backend="numpy"), log=lambda *a: None)
    finally:
        MixBSDF._view_factor = original
    assert len(seen) >= 2 and not any(every for _, _, every in seen) and sum(len(a) for a, _, _ in seen) > 400
    for reference, compiled, _ in seen:
        assert same_bits(reference, compiled)


def test_control_a_last_bit_change_of_the_view_is_seen():
    """wo moved by one ulp changes the factors in their last bits, and the comparison sees it."""
    si = edge_hits()
    idx = np.arange(len(si))
    reference, _ = both_views(MixFactor("fresnel", ior=1.45), si, idx)
    si.wo = np.nextafter(si.wo, 10.0)
    _, moved = both_views(MixFactor("fresnel", ior=1.45), si, idx)
    assert np.allclose(moved, reference, atol=1e-12, equal_nan=True) and not same_bits(moved, reference)


def test_the_view_kernel_refuses_rows_and_indices_it_would_read_past():
    require_compiled()
    import importlib
    twin = importlib.import_module(TWIN)
    rows = np.ones((3, 4))
    with pytest.raises(ValueError, match="view_factor"):
        twin.view_factor(rows, np.ones((3, 1)), rows, None, (1.5, 1 / 1.5))
    with pytest.raises(IndexError, match="view_factor"):
        twin.view_factor(rows, rows, rows, np.array([0, 4]), (1.5, 1 / 1.5))


# -- the pairs' placing and probabilities, a row's eval scatter, a sample's bookkeeping ---------------------
# (mix_jit.place, probabilities, put, write_leaf, spread, mixture: MixBSDF._placed, _probabilities, _eval_pairs,
# _write_leaf, _spread, _mixture on NumPy and compiled)
BOOKKEEPING = ("_placed", "_probabilities", "_write_leaf", "_spread", "_mixture", "_eval_pairs")


def both_ways(bsdf, method, *args):
    """(NumPy's, the compiled) results of MixBSDF method `method` (a function or its name) on copies of
    args, with the arrays it writes into (the arguments) after it: [result, *args]."""
    import copy
    import importlib
    twin = importlib.import_module(TWIN)
    from engine.materials.mix import MixBSDF
    method = getattr(MixBSDF, method) if isinstance(method, str) else method
    out, kept = [], bsdf.compiled
    for compiled in (None, twin):
        mine = copy.deepcopy(args) if method.__name__ in ("_write_leaf", "_mixture") else args
        bsdf.compiled = compiled
        try:
            with np.errstate(all="ignore"):
                out.append([method(bsdf, *mine), *mine])
        finally:
            bsdf.compiled = kept
    return out


def flat_arrays(value):
    """The arrays of a result (nested tuples / lists, a ShadingPoint's leaves left out), in order."""
    if isinstance(value, np.ndarray):
        return [value]
    if isinstance(value, (tuple, list)):
        return [a for v in value for a in flat_arrays(v)]
    return []


def same_results(a, b) -> bool:
    """The same arrays bit for bit, of the same dtypes (but empty ones: np.bincount of no pairs is int64)."""
    xs, ys = flat_arrays(a), flat_arrays(b)
    return len(xs) == len(ys) and all(x.shape == y.shape and same_bits(np.asarray(x, np.float64), np.asarray(y, np.float64))
                                      and (x.dtype == y.dtype or not x.size) for x, y in zip(xs, ys))


def test_the_bookkeeping_of_renders_is_numpys(monkeypatch):
    """Every call of the pair and sample bookkeeping in NumPy renders of a floor of two mixes (a delta
    leaf among them: glass, mirror), repeated compiled on the same inputs: the same bits."""
    from engine import render
    from engine.materials.mix import MixBSDF
    from tests.materials.test_mix import textured_floor_scene
    require_compiled()
    seen = {name: 0 for name in BOOKKEEPING}

    def recorder(name):
        original = getattr(MixBSDF, name)

        def recording(self, *args, **kw):
            if name == "_eval_pairs" and kw:
                args, kw = args + (kw["only"],), {}
            a, b = both_ways(self, original, *args)
            assert same_results(a, b), name
            seen[name] += 1
            return original(self, *args)
        return recording
    for name in BOOKKEEPING:
        monkeypatch.setattr(MixBSDF, name, recorder(name))
    for floor, second in (("diffuse+glass", "fresnel diffuse+glossy"), ("glossy+mirror", "layer weight")):
        scene = textured_floor_scene(MIXES[floor])
        scene.materials.append(MIXES[second])
        scene.meshes[0].material_ids = np.array([0, 2])
        render(scene, RenderSettings(samples=8, seed=2, threads=1, backend="numpy", max_depth=4), log=lambda *a: None)
    assert all(count >= 2 for count in seen.values()), seen           # each scene's first bounce at least


def edge_table(rng, n=500):
    """A mix table's hits with NaN, +-inf, -0 and 0 weights and colours (mix_pair's materials)."""
    numpy_bsdf, compiled, kinds = mix_pair()
    material = rng.integers(0, kinds, n)
    weights = rng.random((numpy_bsdf.leaf_table.shape[1], n))
    weights.flat[rng.choice(weights.size, 40, replace=False)] = np.repeat([np.nan, np.inf, -np.inf, -0.0, 0.0, 1e-300, 1e300, -1.0], 5)
    color = rng.random((3, numpy_bsdf.table.color.shape[1])) * 1.5
    color[:, :4] = np.array([[np.nan, 0.0, 0.0], [np.inf, 1.0, 1.0], [-0.0, -0.0, -0.0], [0.01, 0.02, 0.03]]).T
    return numpy_bsdf, material, weights, color


def test_the_placing_and_probabilities_are_numpys_on_edge_inputs():
    import importlib
    twin = importlib.import_module(TWIN)
    numpy_bsdf, material, weights, color = edge_table(np.random.default_rng(12))
    numpy_bsdf.table.color = color
    for take in (np.arange(len(material)), np.zeros(0, np.int64), np.arange(0, len(material), 7)):
        mat, w = material.take(take), weights.take(take, axis=1)
        placed = twin.place(mat, numpy_bsdf.leaf_count, numpy_bsdf.leaf_table, numpy_bsdf.row_table, w, color)
        hit, leaf, row, weight, colors = placed
        # NumPy's placing of the same weights: _placed with _material_weights giving them
        numpy_bsdf._material_weights = lambda si: ((int(m), np.flatnonzero(mat == m),
                                                    [w[j, mat == m] for j in range(numpy_bsdf.leaf_count[m])])
                                                   for m in np.unique(mat))
        si = ShadingPoint(*(np.zeros((3, len(mat))),) * 5, mat)
        reference = numpy_bsdf._placed(si)
        assert same_results(placed, reference) and len(hit) == numpy_bsdf.leaf_count.take(mat).sum()
        with np.errstate(all="ignore"):
            assert same_results(twin.probabilities(hit, weight, colors, ALBEDO_FLOOR, len(mat)),
                                numpy_bsdf._probabilities(hit, weight, colors, len(mat)))
    assert np.isnan(placed[3]).any() and np.isinf(placed[3]).any()
    # control: one ulp of one colour changes a probability in its last bit, and the comparison sees it
    moved = colors.copy()
    moved[0, 5] = np.nextafter(moved[0, 5], 10.0)
    a, b = twin.probabilities(hit, weight, moved, 0.05, len(mat)), twin.probabilities(hit, weight, colors, 0.05, len(mat))
    assert not same_results(a, b)


def test_control_a_perturbed_kernel_is_told_apart(monkeypatch):
    """A real control of the NumPy-vs-compiled comparison (both_ways, same_results): the compiled
    probabilities and write_leaf kernels swapped for copies with one operation changed (w / t as
    w x (1 / t), as a careless rewrite might) give other bits, and the comparison the render and
    edge-input tests use says so; the unchanged kernels on the same inputs agree."""
    import importlib
    from types import SimpleNamespace
    from engine.materials.protocol import DELTA_LOBE, DIFFUSE_LOBE
    twin = importlib.import_module(TWIN)
    nb = twin.nb
    numpy_bsdf, material, weights, color = edge_table(np.random.default_rng(14))
    weights, color = np.abs(np.nan_to_num(weights, posinf=2.0, neginf=2.0)), np.random.default_rng(15).random(color.shape)
    hit, _, _, weight, colors = twin.place(material, numpy_bsdf.leaf_count, numpy_bsdf.leaf_table, numpy_bsdf.row_table,
                                           weights, color)
    n = len(material)
    mine = np.arange(0, n, 2)
    pairs = np.searchsorted(hit, mine)
    p_c = np.random.default_rng(16).random(n) + 0.1
    s = SimpleNamespace(wi=np.ones((3, len(mine))), value=np.random.default_rng(17).random((3, len(mine))),
                        pdf=np.ones(len(mine)), flags=np.where(np.arange(len(mine)) % 3, DELTA_LOBE, DIFFUSE_LOBE).astype(np.int8))

    def compare():
        """(probabilities the same, write_leaf the same) on NumPy and the compiled path."""
        a, b = both_ways(numpy_bsdf, "_probabilities", hit, weight, colors, n)
        arrays = (np.zeros((3, n)), np.zeros((3, n)), np.zeros(n), np.zeros(n, np.int8), np.zeros(n, bool))
        c, d = both_ways(numpy_bsdf, "_write_leaf", mine, pairs, s, weight, p_c, *arrays)
        return same_results(a, b), same_results(c[6:], d[6:])
    assert compare() == (True, True)

    @nb.njit(error_model="numpy")
    def probabilities_times_inverse(hit, weight, color, floor, n):
        size = hit.shape[0]
        rate, prob, total = np.empty(size), np.empty(size), np.zeros(n)
        for p in range(size):
            albedo = (color[0, p] + color[1, p] + color[2, p]) / 3.0
            if albedo < floor:
                albedo = floor
            rate[p] = weight[p] * albedo
            total[hit[p]] += rate[p]
        for p in range(size):
            t = total[hit[p]]
            prob[p] = rate[p] * (1.0 / t) if t > 0.0 else 0.0           # the change: rate / t
        return prob, total

    @nb.njit(error_model="numpy")
    def write_leaf_times_inverse(mine, pairs, s_wi, s_value, s_pdf, s_flags, delta_lobe, weight, p_c, wi, value, pdf,
                                 flags, delta):
        for i in range(mine.shape[0]):
            h, c = mine[i], pairs[i]
            wi[0, h], wi[1, h], wi[2, h] = s_wi[0, i], s_wi[1, i], s_wi[2, i]
            flags[h] = s_flags[i]
            delta[h] = (s_flags[i] & delta_lobe) != 0
            if delta[h]:
                w_over_p = weight[c] * (1.0 / p_c[h])                  # the change: weight / p_c
                for k in range(3):
                    value[k, h] = s_value[k, i] * w_over_p
                pdf[h] = p_c[h] * s_pdf[i]
    monkeypatch.setattr(twin, "_probabilities", probabilities_times_inverse)
    assert compare() == (False, True)
    monkeypatch.setattr(twin, "_write_leaf", write_leaf_times_inverse)
    assert compare() == (False, False)


def test_the_placing_control_a_swapped_leaf_is_seen():
    """Control: a leaf table with two leaves of one material swapped places other pairs."""
    import importlib
    twin = importlib.import_module(TWIN)
    numpy_bsdf, material, weights, color = edge_table(np.random.default_rng(13))
    args = (material, numpy_bsdf.leaf_count, numpy_bsdf.leaf_table, numpy_bsdf.row_table, weights, color)
    swapped = numpy_bsdf.leaf_table.copy()
    swapped[0, [0, 1]] = swapped[0, [1, 0]]
    assert not same_results(twin.place(*args), twin.place(material, numpy_bsdf.leaf_count, swapped, *args[3:]))


def test_a_samples_bookkeeping_is_numpys_on_edge_inputs():
    """_write_leaf, _spread and _mixture on NaN / inf / -0 values, pdfs and probabilities, delta and non-delta
    lobes, dead hits (p_c 0) and no hits."""
    from types import SimpleNamespace
    from engine.materials.protocol import DELTA_LOBE, DIFFUSE_LOBE, REFLECTION_LOBE
    numpy_bsdf, _, _ = mix_pair()
    rng = np.random.default_rng(21)
    for n in (300, 0):
        count = rng.integers(1, 4, n)
        hit = np.repeat(np.arange(n), count)
        p_c = rng.random(n) * (rng.random(n) > 0.1)
        p_c[:8] = (np.nan, np.inf, -0.0, 0.0, 1e-300, 1.0, -1.0, 0.5)[:len(p_c[:8])]
        weight = rng.random(len(hit))
        mine = np.sort(rng.choice(n, n // 2, replace=False))
        pairs = np.searchsorted(hit, mine)
        s = SimpleNamespace(wi=rng.normal(size=(3, len(mine))), value=rng.random((3, len(mine))),
                            pdf=rng.random(len(mine)),
                            flags=rng.choice([DELTA_LOBE | REFLECTION_LOBE, DIFFUSE_LOBE | REFLECTION_LOBE], len(mine)).astype(np.int8))
        s.value[:, :3], s.pdf[:3] = np.nan, (np.inf, -0.0, np.nan)[:len(s.pdf[:3])]
        arrays = (np.zeros((3, n)), np.zeros((3, n)), np.zeros(n), np.full(n, 5, np.int8), np.zeros(n, bool))
        a, b = both_ways(numpy_bsdf, "_write_leaf", mine, pairs, s, weight, p_c, *arrays)
        assert same_results(a[6:], b[6:])
        delta = a[-1]
        a, b = both_ways(numpy_bsdf, "_spread", hit, delta, p_c)
        assert same_results(a, b)
        spread = a[0][0]
        f_sum, p_sum = rng.random((3, n)), rng.random(n) * (rng.random(n) > 0.2)
        p_sum[:6] = (np.nan, np.inf, -0.0, 0.0, 1e-300, -1.0)[:len(p_sum[:6])]
        a, b = both_ways(numpy_bsdf, "_mixture", spread, f_sum, p_sum, np.zeros((3, n)), np.zeros(n))
        assert same_results(a[4:], b[4:])
    assert len(spread) == 0
    # control: the compiled write_leaf told another delta flag keeps other hits' values
    import importlib
    twin = importlib.import_module(TWIN)
    n = 300
    arrays = [(np.zeros((3, n)), np.zeros((3, n)), np.zeros(n), np.full(n, 5, np.int8), np.zeros(n, bool)) for _ in range(2)]
    p_c = np.full(n, 0.5)
    mine, pairs = np.arange(0, n, 2), np.arange(0, n, 2)
    s = SimpleNamespace(wi=np.ones((3, len(mine))), value=np.ones((3, len(mine))), pdf=np.ones(len(mine)),
                        flags=np.where(np.arange(len(mine)) % 3, DELTA_LOBE, DIFFUSE_LOBE).astype(np.int8))
    twin.write_leaf(mine, pairs, s, DELTA_LOBE, np.ones(n), p_c, *arrays[0])
    twin.write_leaf(mine, pairs, s, DIFFUSE_LOBE, np.ones(n), p_c, *arrays[1])
    assert not same_results(arrays[0], arrays[1])


def test_the_bookkeeping_kernels_refuse_what_they_would_read_past():
    require_compiled()
    import importlib
    from types import SimpleNamespace
    twin = importlib.import_module(TWIN)
    table = np.array([[0, 1]])
    with pytest.raises(IndexError, match="place"):
        twin.place(np.array([1]), np.array([2]), table, table, np.ones((2, 1)), np.ones((3, 2)))
    with pytest.raises(IndexError, match="place"):
        twin.place(np.array([0]), np.array([2]), np.array([[0, 5]]), table, np.ones((2, 1)), np.ones((3, 2)))
    with pytest.raises(ValueError, match="place"):
        twin.place(np.array([0]), np.array([2]), table, table, np.ones((1, 1)), np.ones((3, 2)))
    with pytest.raises(IndexError, match="probabilities"):
        twin.probabilities(np.array([0, 3]), np.ones(2), np.ones((3, 2)), 0.05, 2)
    with pytest.raises(IndexError, match="put"):
        twin.put(np.zeros((3, 2)), np.zeros(2), np.array([2]), np.ones((3, 1)), np.ones(1))
    s = SimpleNamespace(wi=np.ones((3, 1)), value=np.ones((3, 1)), pdf=np.ones(1), flags=np.array([16], np.int8))
    with pytest.raises(IndexError, match="write_leaf"):
        twin.write_leaf(np.array([2]), np.array([0]), s, 16, np.ones(1), np.ones(2), np.zeros((3, 2)), np.zeros((3, 2)),
                        np.zeros(2), np.zeros(2, np.int8), np.zeros(2, bool))
    # write_leaf: every array it reads or writes of the wrong shape (n = 3 hits, one sample of hit 2)
    n = 3
    out = dict(wi=np.zeros((3, n)), value=np.zeros((3, n)), pdf=np.zeros(n), flags=np.zeros(n, np.int8),
               delta=np.zeros(n, bool))
    fine = dict(mine=np.array([2]), pairs=np.array([0]), s=s, weight=np.ones(1), p_c=np.full(n, 0.5), **out)

    def write(**changed):
        a = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in {**fine, **changed}.items()}
        twin.write_leaf(a["mine"], a["pairs"], a["s"], 16, a["weight"], a["p_c"], a["wi"], a["value"], a["pdf"],
                        a["flags"], a["delta"])
        return a
    assert write()["pdf"][2] == 0.5                           # the shapes it takes
    short = dict(wi=np.ones((3, 0)), value=np.ones((3, 0)), pdf=np.ones(0), flags=np.zeros(0, np.int8))
    wrong = [dict(p_c=np.ones(1)),                            # reviewer's proof: p_c[2] read past its end
             dict(p_c=np.ones((1, n))), dict(pairs=np.array([0, 0])), dict(mine=np.array([[2]])),
             dict(s=SimpleNamespace(**{**vars(s), "flags": np.array([16, 16], np.int8)})),
             dict(s=SimpleNamespace(**{**vars(s), "flags": np.zeros(0, np.int8)})),
             dict(s=SimpleNamespace(**{**vars(s), "pdf": np.ones(2)})),
             dict(s=SimpleNamespace(**{**vars(s), "value": np.ones((3, 2))})),
             dict(s=SimpleNamespace(**{**vars(s), "wi": np.ones((2, 1))})),
             dict(s=SimpleNamespace(**short)), dict(weight=np.ones((1, 1)))]
    wrong += [{k: v[..., :2]} for k, v in out.items()] + [{k: np.zeros((2,) + v.shape, v.dtype)} for k, v in out.items()]
    for changed in wrong:
        with pytest.raises(ValueError, match="write_leaf"):
            write(**changed)
    # the reviewer's short s.flags: two samples of hits 0, 1 with one flag
    s2 = SimpleNamespace(wi=np.ones((3, 2)), value=np.ones((3, 2)), pdf=np.ones(2), flags=np.array([16], np.int8))
    with pytest.raises(ValueError, match="write_leaf"):
        write(mine=np.array([0, 1]), pairs=np.array([0, 0]), s=s2)
    with pytest.raises(IndexError, match="spread"):
        twin.spread(np.array([0, 2]), np.zeros(2, bool), np.ones(2))
    # spread: p_c, delta of other shapes (p_c[h] read for h < len(delta)), a hit table of two axes
    for hit, delta, p_c in ((np.arange(4), np.zeros(4, bool), np.ones(1)),     # the reviewer's proof
                            (np.arange(2), np.zeros(2, bool), np.ones(3)),
                            (np.arange(2), np.zeros((1, 2), bool), np.ones((1, 2))),
                            (np.zeros((1, 2), np.int64), np.zeros(2, bool), np.ones(2))):
        with pytest.raises(ValueError, match="spread"):
            twin.spread(hit, delta, p_c)
    assert [len(x) for x in twin.spread(np.arange(4), np.zeros(4, bool), np.ones(4))] == [4, 4, 4]
    with pytest.raises(IndexError, match="mixture"):
        twin.mixture(np.array([2]), np.ones((3, 2)), np.ones(2), np.zeros((3, 2)), np.zeros(2))
