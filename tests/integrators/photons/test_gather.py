"""The gather's search and sums (engine/integrators/photons/gather.py) and their numba twin
(gather_jit.py): the pairs are every photon within the radius under the gather's rules (a brute
force over all pairs, with controls), sorted by query then photon; the twin gives the same pairs and
the same sums bit for bit on the calls of a real render, and on made-up queries outside the grid,
at NaN, inf and -0 and into an empty pass, with and without the slots' column tables
(photon_map.py BatchMaps.columns, checked against a search of the keys)."""
import copy

import numpy as np
import pytest

import engine.integrators.photons.caustics as caustics_module
from engine import api
from engine.core.settings import RenderSettings
from engine.geometry.scene_geometry import Counters
from engine.integrators.photons import gather, photon_map
from engine.integrators.photons.photon_map import BatchMaps
from engine.integrators.photons.tracing import Stored
from engine.rendering.session import PreparedScene
from engine.scene.builtin import caustic_scene
from tests.backend_capture import require_compiled


def made_up_maps(n=20000, seed=5, scales=(1.0, 4.0)):
    """Two passes of photons on a floor and a wall, with chains and segments."""
    rng = np.random.default_rng(seed)
    position = rng.random((3, n)) * [[1.0], [1.0], [0.02]]
    wall = rng.random(n) < 0.3
    position[2, wall] = rng.random(wall.sum())
    position[1, wall] = 0.5 + rng.normal(0, 0.01, wall.sum())
    normal = np.where(wall, [[0.0], [1.0], [0.0]], [[0.0], [0.0], [1.0]])
    normal[:, rng.random(n) < 0.1] *= -1.0
    stored = Stored(position, -normal, rng.random((3, n)), normal, rng.integers(2, 6, n).astype(np.int32),
                    rng.integers(0, 2, n), rng.integers(0, 3, (3, n)).astype(np.int16))
    return BatchMaps(stored, (0, 1), (0.05, 0.04), scales), stored


def made_up_queries(maps, m=400, seed=6):
    rng = np.random.default_rng(seed)
    points = maps.position[:, rng.integers(0, maps.count, m)] + rng.normal(0, 0.02, (3, m))
    points[:, :10] += 5.0                                      # outside every grid
    facing = np.where(rng.random(m) < 0.8, [[0.0], [0.0], [1.0]], [[0.0], [1.0], [0.0]])
    local = rng.integers(0, len(maps.offsets) - 1, m)
    radius = maps.radius.take(local) * np.where(local >= len(maps.passes), 4.0, 1.0)
    return points, facing, local, radius, rng.integers(2, 6, m), rng.integers(-1, 3, (3, m))


def brute_pairs(maps, stored, points, facing, local, radius, segments, budget):
    """Every (query, stored photon) under the rules, by brute force over the stored photons."""
    found = set()
    p = len(maps.passes)
    for q in range(points.shape[1]):
        label = maps.passes[local[q] % p]
        d = stored.position - points[:, q:q + 1]
        ok = (stored.label == label) & ((d * d).sum(axis=0) <= radius[q] ** 2)
        ok &= (facing[:, q:q + 1] * stored.normal).sum(axis=0) > gather.SAME_SIDE_COS
        ok &= stored.segments <= segments[q]
        ok &= (stored.chain <= budget[:, q:q + 1]).all(axis=0)
        found.update((q, j) for j in np.flatnonzero(ok))
    return found


def stored_index(maps, stored, photon):
    """The stored photon each of the maps' photons is (checked by its position)."""
    index = maps.source.take(photon)
    assert np.array_equal(stored.position.take(index, axis=1), maps.position.take(photon, axis=1))
    return index


def test_the_pairs_are_every_photon_within_the_radius_under_the_rules():
    maps, stored = made_up_maps()
    args = made_up_queries(maps)
    query, photon = gather.pairs(maps, *args)
    got = set(zip(query.tolist(), stored_index(maps, stored, photon).tolist()))
    expected = brute_pairs(maps, stored, *args)
    assert len(expected) > 1000 and got == expected
    assert np.all(np.diff(query) >= 0) and np.all(np.diff(photon)[np.diff(query) == 0] > 0)     # the sums' order
    points, facing, local, radius, segments, budget = args
    control = set(zip(*(a.tolist() for a in gather.pairs(maps, points, facing, local, radius * 0.97, segments,
                                                          budget))))
    assert len(control) < len(got)                           # a smaller radius finds fewer: the check can fail


def test_the_flux_sums_add_each_querys_photons_in_the_order_of_the_pairs():
    maps, _ = made_up_maps()
    args = made_up_queries(maps)
    query, photon = gather.pairs(maps, *args)
    sums = gather.flux_sums(maps, *args)
    expected = np.zeros_like(sums)
    for q, j in zip(query, photon):
        expected[:, q] += maps.flux[:, j]
    assert np.array_equal(sums, expected)
    flipped = np.zeros_like(sums)                            # control: the other order is other bits somewhere
    for q, j in zip(query[::-1], photon[::-1]):
        flipped[:, q] += maps.flux[:, j]
    assert not np.array_equal(flipped, expected)


def recorded_calls(limit=24):
    """The arguments of the gather's calls in a caustic-room render (NumPy backend)."""
    calls, real = [], gather.pairs

    def recording(maps, *args):
        if len(calls) < limit:
            calls.append((maps,) + tuple(None if a is None else np.array(a, copy=True) for a in args))
        return real(maps, *args)
    gather.pairs = recording
    try:
        api.render(caustic_scene((24, 24)), RenderSettings(samples=10, threads=1, backend="numpy", photons_per_pass=2000,
                                                           caustics_method="photons"), log=lambda m: None)
    finally:
        gather.pairs = real
    return calls


def test_the_twin_gives_the_same_pairs_and_sums_bit_for_bit():
    require_compiled()
    from engine.integrators.photons import gather_jit
    maps, _ = made_up_maps()
    calls = [(maps,) + made_up_queries(maps), (maps,) + made_up_queries(maps)[:4] + (None, None)]
    calls += recorded_calls()
    assert sum(len(gather.pairs(*c)[0]) for c in calls) > 5000
    for c in calls:
        for a, b in zip(gather.pairs(*c), gather_jit.pairs(*c)):
            assert a.dtype == b.dtype and np.array_equal(a, b)
        assert np.array_equal(gather.flux_sums(*c), gather_jit.flux_sums(*c))
    maps, points, facing, local, radius, segments, budget = calls[0]
    nudged = points.copy()                       # control: a query moved by an ulp onto a photon changes a sum
    q, j = gather.pairs(maps, points, facing, local, radius, segments, budget)
    nudged[:, q[0]] = maps.position[:, j[0]] + np.spacing(maps.position[:, j[0]])
    assert not np.array_equal(gather_jit.flux_sums(maps, nudged, facing, local, radius, segments, budget),
                              gather.flux_sums(maps, points, facing, local, radius, segments, budget))


def test_the_column_table_is_where_each_column_starts():
    """Each slot's table: entry x dims_y + y the first photon of that column (a search of the slot's
    keys for the column's first key), the last entry the slot's count; none past the cap."""
    maps, _ = made_up_maps()
    slots = len(maps.offsets) - 1
    assert np.all(np.diff(maps.column_at) > 0)
    for s in range(slots):
        keys = maps.keys[maps.offsets[s]:maps.offsets[s + 1]]
        n_columns = maps.dims[0, s] * maps.dims[1, s]
        table = maps.columns[maps.column_at[s]:maps.column_at[s + 1]]
        first_keys = s * maps.stride + np.arange(n_columns + 1) * maps.dims[2, s]
        assert table.dtype == np.int32 and np.array_equal(table, np.searchsorted(keys, first_keys, "left"))
    keys = maps.keys[:maps.offsets[1]]
    moved = keys.copy()                      # control: one photon in the next column is another table
    moved[len(moved) // 2] += maps.dims[2, 0]
    assert not np.array_equal(photon_map.column_table(np.sort(moved), maps.dims[:, 0]),
                              photon_map.column_table(keys, maps.dims[:, 0]))
    dims = np.array([photon_map.MIN_COLUMNS, 2, 7])             # twice MIN_COLUMNS columns
    enough = 2 * photon_map.MIN_COLUMNS // photon_map.COLUMNS_PER_PHOTON
    assert len(photon_map.column_table(np.arange(enough) * 7, dims)) == 2 * photon_map.MIN_COLUMNS + 1
    assert len(photon_map.column_table(np.arange(enough - 1) * 7, dims)) == 0          # past the cap: none


def edge_calls(maps):
    """Made-up queries at NaN, inf and -0, with a NaN or infinite radius, none at all, and into a
    pass with no photon."""
    points, facing, local, radius, segments, budget = made_up_queries(maps, m=60, seed=8)
    points[0, 10], points[:, 11], radius[12] = np.nan, np.nan, np.nan
    points[1, 13], points[2, 14], radius[15] = np.inf, -np.inf, np.inf
    points[:, 16], points[2, 17] = -0.0, -0.0
    points[0, 18], radius[18] = np.inf, np.inf                    # inf - inf: NaN
    empty = tuple(a[..., :0] for a in (points, facing, local, radius, segments, budget))
    rng = np.random.default_rng(9)
    n = 500
    stored = Stored(rng.random((3, n)) * [[1.0], [1.0], [0.0]] + [[0.0], [0.0], [0.5]], np.tile([[0.0], [0.0], [-1.0]], (1, n)), rng.random((3, n)),
                    np.tile([[0.0], [0.0], [1.0]], (1, n)), np.full(n, 2, np.int32), np.zeros(n, np.int64),
                    np.zeros((3, n), np.int16))
    half = BatchMaps(stored, (0, 1), (0.1, 0.1), (1.0, 4.0))      # pass 1 (slots 1 and 3) has no photon
    m = 40
    into = (rng.random((3, m)) * [[1.0], [1.0], [0.05]] + [[0.0], [0.0], [0.5]], np.tile([[0.0], [0.0], [1.0]], (1, m)), np.arange(m) % 4, np.full(m, 0.1))
    return [(maps, points, facing, local, radius, segments, budget), (maps,) + empty, (half,) + into]


def without_tables(maps):
    """The maps with every slot's column table dropped: the twin searches the keys, as gather.py does."""
    bare = copy.copy(maps)
    bare.columns, bare.column_at = np.zeros(0, np.int32), np.zeros_like(maps.column_at)
    return bare


def column_runs(maps, points, local, radius):
    """How many (query, column) pairs of the queries' boxes have photons all within, some within and
    none within the box's z cells (the cases of gather_jit._run)."""
    first, last, meets = gather.cell_ranges(maps, points, local, radius)
    found = np.zeros(3, np.int64)
    for q in np.flatnonzero(meets):
        k = local[q]
        keys = maps.keys[maps.offsets[k]:maps.offsets[k + 1]] - k * maps.stride
        for ix in range(first[0, q], last[0, q] + 1):
            for iy in range(first[1, q], last[1, q] + 1):
                column = ix * maps.dims[1, k] + iy
                z = keys[keys // maps.dims[2, k] == column] % maps.dims[2, k]
                inside = (z >= first[2, q]) & (z <= last[2, q])
                if len(z):
                    found[0 if inside.all() else 1 if inside.any() else 2] += 1
    return found


def test_the_twin_gives_the_same_bits_at_the_edges_and_without_tables():
    require_compiled()
    from engine.integrators.photons import gather_jit
    maps, _ = made_up_maps()
    calls = edge_calls(maps) + [(maps,) + made_up_queries(maps)]
    calls += [(without_tables(c[0]),) + c[1:] for c in calls]
    assert np.all(column_runs(maps, *(calls[3][i] for i in (1, 3, 4))) > 100)     # every kind of column run
    with np.errstate(invalid="ignore"):
        for c in calls:
            for a, b in zip(gather.pairs(*c), gather_jit.pairs(*c)):
                assert a.dtype == b.dtype and np.array_equal(a, b)
            assert np.array_equal(gather.flux_sums(*c), gather_jit.flux_sums(*c))
        assert np.all(gather.flux_sums(*calls[0])[:, [10, 11, 12, 18]] == 0.0)
        assert len(gather.pairs(*calls[2])[0]) > 100
    wrong = copy.copy(maps)                  # control: every run of slot 0's table one photon short
    wrong.columns = maps.columns.copy()
    table = wrong.columns[:maps.column_at[1]]
    table[np.flatnonzero(np.diff(table) > 0) + 1] -= 1
    assert not np.array_equal(gather.flux_sums(*calls[3]), gather_jit.flux_sums(wrong, *calls[3][1:]))


def recorded_lambert_calls(limit=12):
    """The arguments of gather.lambert_radiance's calls in a caustic-room render (NumPy backend), `out`
    as it was before each call."""
    calls, real = [], gather.lambert_radiance

    def recording(maps, *args):
        if len(calls) < limit:
            calls.append((maps,) + tuple(a.copy() if isinstance(a, np.ndarray) else a for a in args))
        return real(maps, *args)
    caustics_module.gather.lambert_radiance = recording
    try:
        api.render(caustic_scene((24, 24)), RenderSettings(samples=10, threads=1, backend="numpy", photons_per_pass=2000,
                                                           caustics_method="photons"), log=lambda m: None)
    finally:
        caustics_module.gather.lambert_radiance = real
    return calls


def made_up_lambert_calls():
    """lambert_radiance on the made-up maps: a subset of rows, wide and narrow, albedo with NaN, inf
    and -0, points at NaN and inf, no limits; and into a pass with no photon."""
    maps, _ = made_up_maps()
    (_, points, facing, _, _, segments, budget), _, (half, *into) = edge_calls(maps)
    rng = np.random.default_rng(10)
    m = points.shape[1]
    albedo = rng.random((3, m))
    albedo[0, 1], albedo[1, 2], albedo[2, 3], albedo[:, 4] = np.nan, np.inf, -0.0, 0.0
    passes, wide = rng.integers(0, 2, m), rng.random(m) < 0.4
    rows = np.union1d(np.flatnonzero(rng.random(m) < 0.8), [1, 2, 3, 4])
    rows = rows[rows != 0]                   # row 0 is not asked: left as it was
    n = into[0].shape[1]
    return [(maps, rows, points, facing, passes, wide, 4.0, segments, budget, albedo, rng.random((3, m))),
            (maps, rows[::2], points, facing, passes, wide, 4.0, None, None, albedo, np.zeros((3, m))),
            (half, np.arange(n), into[0], into[1], np.arange(n) % 2, np.arange(n) % 3 == 0, 4.0, None, None,
             rng.random((3, n)), np.zeros((3, n)))]


def test_the_twins_lambert_radiance_is_gather_pys():
    """The caustic radiance of a batch's rows on a Lambertian BSDF: the same bits in the same
    places (the other columns of `out` left as they were), on a render's calls and made-up ones."""
    require_compiled()
    from engine.integrators.photons import gather_jit
    calls = recorded_lambert_calls() + made_up_lambert_calls()
    assert len(calls) > 10 and sum(np.count_nonzero(c[-2][:, c[1]]) for c in calls) > 1000
    outs = []
    for *args, out in calls:
        expected, got = out.copy(), out.copy()
        with np.errstate(invalid="ignore"):
            gather.lambert_radiance(*args, expected)
            gather_jit.lambert_radiance(*args, got)
        assert np.array_equal(expected, got, equal_nan=True)
        outs.append(expected)
    assert sum(np.count_nonzero(o > 0) for o in outs) > 1000
    assert np.isnan(outs[-3][0, 1]) and np.array_equal(outs[-3][:, 0], calls[-3][-1][:, 0])
    *args, out = calls[-3]                   # control: the wide radius' scale off by an ulp is other bits
    args[6] = np.nextafter(args[6], 5.0)
    nudged = out.copy()
    with np.errstate(invalid="ignore"):
        gather_jit.lambert_radiance(*args, nudged)
    assert not np.array_equal(nudged, outs[-3], equal_nan=True)


def test_a_render_is_the_same_on_both_backends():
    require_compiled()
    images = [api.render(caustic_scene((12, 12)), RenderSettings(samples=5, threads=1, backend=b, photons_per_pass=1500,
                                                                 caustics_method="photons"), log=lambda m: None).image
              for b in ("numpy", "numba")]
    assert np.array_equal(images[0], images[1])


def test_a_batch_gathers_every_pass_in_one_call(monkeypatch):
    """The points of the eight passes of a batch, narrow and wide, go to one call of the kernels."""
    prepared = PreparedScene(caustic_scene((8, 8)), RenderSettings(caustics_method="photons", photons_per_pass=1000,
                                                                   backend="numpy"), log=lambda *a: None)
    photons = prepared.tracer.photons
    calls = []
    real = gather.flux_sums
    monkeypatch.setattr(gather, "flux_sums", lambda maps, *a: calls.append(a[2].copy()) or real(maps, *a))
    monkeypatch.setattr(caustics_module, "SECONDARY_GATHER", 1.0)
    maps = photons.maps_of(0, Counters())
    m = 64
    from engine.materials.lambert import Lambertian
    from engine.materials.protocol import ShadingPoint
    up = np.tile([[0.0], [0.0], [1.0]], (1, m))
    si = ShadingPoint(up.copy(), up.copy(), up.copy(), up.copy(), np.ones((3, m)), np.zeros(m, np.int64), False, None,
                      None)
    points = maps.position[:, :m]
    sample = np.arange(m) % 8
    out = photons.radiance(sample, Lambertian([], None), si, points, up, Counters(), secondary=np.arange(m) % 3 == 0)
    assert len(calls) == 1 and set(calls[0].tolist()) == set(range(16)) and (out > 0).any()
    one = [photons.map_of(k, Counters()).radiance(Lambertian([], None), si.take(np.flatnonzero(sample == k)),
                                                  points[:, sample == k], up[:, sample == k],
                                                  scale=1.0) for k in range(8)]
    narrow = np.arange(m) % 3 != 0
    for k in range(8):
        mine = sample == k
        assert np.array_equal(out[:, mine & narrow], one[k][:, narrow[mine]])     # one call = pass by pass
