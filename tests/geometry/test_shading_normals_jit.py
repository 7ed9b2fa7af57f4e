"""The compiled shading-normal passes (engine/geometry/shading_normals_jit.py: Phong normals at hits, the
shadow-terminator lift; engine/nodes/normals_jit.py: bump shadowing) against the NumPy code they replace
(engine/geometry/shading_normals.py SmoothNormals, SceneGeometry.terminator_lift, PathTracer.bump_shadowing),
bit for bit, on random corners and hits with flat triangles, cancelling corners, cutoff 0, other kinds and NaN;
each with a control that a changed input differs."""
from types import SimpleNamespace

import numpy as np

from engine.geometry.scene_geometry import SPHERE, TRIANGLE, SceneGeometry
from engine.geometry.shading_normals import SmoothNormals
from engine.integrators.path_tracer import PathTracer
from engine.scene.model import TriangleMesh
from tests.backend_capture import require_compiled


def meshes(rng, t=60):
    """Three meshes: smooth with cutoff 0.1, smooth with cutoff 0 (no lift), half smooth with cutoff 0.3."""
    out = []
    for k, (cut, smooth) in enumerate(((0.1, None), (0.0, None), (0.3, np.arange(t) % 2 == 0))):
        vertices = rng.normal(size=(3 * t, 3))
        mesh = TriangleMesh(f"M{k}", vertices, np.arange(3 * t).reshape(t, 3), np.zeros(t, np.int64))
        normals = rng.normal(size=(t, 3, 3))
        normals /= np.linalg.norm(normals, axis=2)[:, :, None]
        normals[:3, 1] = -normals[:3, 0]                   # corners that cancel at u = 0.5, v = 0
        normals[:3, 2] = 0.0
        mesh.normals, mesh.smooth, mesh.terminator_offset = normals, smooth, cut
        out.append(mesh)
    triangles = np.concatenate([m.vertices.take(m.triangles.reshape(-1), axis=0).reshape(-1, 3, 3) for m in out])
    return out, triangles


def hits(rng, count, m):
    prim = rng.integers(0, count, m)
    u, v = rng.random(m) * 0.5, rng.random(m) * 0.5
    u[:20], v[:20], prim[:20] = 0.5, 0.0, np.arange(20) % 3      # cancelling corners
    u[20], prim[20] = np.nan, 0                                  # a NaN barycentric
    kind = np.where(rng.random(m) < 0.15, SPHERE, TRIANGLE).astype(np.int8)
    return SimpleNamespace(kind=kind, prim=prim, u=u, v=v)


def test_phong_normals_are_the_numpy_numbers():
    require_compiled()
    from engine.geometry import shading_normals_jit
    rng = np.random.default_rng(11)
    ms, triangles = meshes(rng)
    smooth = SmoothNormals(ms)
    h = hits(rng, len(triangles), 400)
    geometric = rng.normal(size=(3, 400))
    expected = smooth.shading(h.prim, h.u, h.v, geometric)
    smooth.jit = shading_normals_jit
    got = smooth.shading(h.prim, h.u, h.v, geometric)
    assert np.array_equal(got, expected, equal_nan=True)
    assert (got == geometric).all(axis=0).sum() > 20            # flat, cancelling and NaN columns: the geometric
    assert not np.array_equal(smooth.shading(h.prim, h.v, h.u, geometric), expected, equal_nan=True)   # control


def test_terminator_lift_is_the_numpy_numbers():
    require_compiled()
    from engine.geometry import shading_normals_jit
    rng = np.random.default_rng(12)
    ms, triangles = meshes(rng)
    smooth = SmoothNormals(ms)
    m = 500
    h = hits(rng, len(triangles), m)
    facing = rng.normal(size=(3, m))
    geometry = SimpleNamespace(smooth=smooth, triangles=triangles)
    for span in (slice(0, m), slice(37, 290), slice(5, 5)):
        smooth.jit = None
        expected = SceneGeometry.terminator_lift(geometry, h, span, facing)
        smooth.jit = shading_normals_jit
        got = SceneGeometry.terminator_lift(geometry, h, span, facing)
        if expected is None:
            assert got is None
            continue
        assert np.array_equal(got[0], expected[0], equal_nan=True) and np.array_equal(got[1], expected[1])
        assert (expected[1] == 0.0).any() and (expected[1] > 0.0).any()
        moved = SimpleNamespace(kind=h.kind, prim=h.prim, u=h.u, v=np.nextafter(h.v, 1.0))        # control
        assert not np.array_equal(SceneGeometry.terminator_lift(geometry, moved, span, facing)[0], expected[0],
                                  equal_nan=True)


def bump_case(rng, m, repeat, flat):
    direction = rng.normal(size=(3, m))
    normal = rng.normal(size=(3, m))
    normal /= np.linalg.norm(normal, axis=0)
    shading = None if flat else normal + 0.3 * rng.normal(size=(3, m))
    towards = np.where((direction * normal).sum(axis=0) < 0.0, 1.0, -1.0)
    n = rng.normal(size=(3, m))
    n /= np.linalg.norm(n, axis=0)
    same = rng.random(m) < 0.3                        # the normal input left these alone
    n[:, same] = ((normal if flat else shading) * towards)[:, same]
    n[:, 0] = np.nan if m > 1 else n[:, 0]
    wi = rng.normal(size=(3, m * repeat))
    wi /= np.linalg.norm(wi, axis=0)
    wi[:, 1 * repeat] = n[:, 1]                       # cos = 1 exactly
    diffuse = rng.random(m * repeat) < 0.5
    points = SimpleNamespace(direction=direction, normal=normal, shading=shading)
    si = SimpleNamespace(lookup=SimpleNamespace(points=points), n=n)
    return si, wi, diffuse


def test_bump_shadowing_is_the_numpy_numbers():
    require_compiled()
    from engine.nodes import normals_jit
    rng = np.random.default_rng(13)
    for repeat in (1, 3):
        for flat in (False, True):
            si, wi, diffuse = bump_case(rng, 300, repeat, flat)
            for is_eval in (True, False):
                tracer = SimpleNamespace(normals_jit=None, textures=SimpleNamespace(
                    textures=SimpleNamespace(cycles_version=(5, 0))))
                expected = PathTracer.bump_shadowing(tracer, si, wi, diffuse, is_eval, repeat)
                tracer.normals_jit = normals_jit
                got = PathTracer.bump_shadowing(tracer, si, wi, diffuse, is_eval, repeat)
                assert np.array_equal(got, expected, equal_nan=True)
                assert ((expected > 0.0) & (expected < 1.0)).any() and (expected == 0.0).any()
                assert not np.array_equal(PathTracer.bump_shadowing(tracer, si, wi, ~diffuse, is_eval, repeat),
                                          expected, equal_nan=True)                           # control
                one = PathTracer.bump_shadowing(tracer, si, wi, True, is_eval, repeat)       # one bool for all
                tracer.normals_jit = None
                assert np.array_equal(one, PathTracer.bump_shadowing(tracer, si, wi, np.ones(len(diffuse), bool),
                                                                     is_eval, repeat), equal_nan=True)


# -- Cycles 3.x's ensure_valid_reflection (engine/geometry/shading_normals.py), compiled ---------------
def recorded_reflections(limit=12):
    """[(ng, i, n)] of the first `limit` calls of ensure_valid_reflection in a 16 x 16, 4 spp NumPy render
    of tests/geometry/test_shading_normals.py's box room with a smooth, low-poly mirror ball."""
    from engine import api
    from engine.core.settings import RenderSettings
    from engine.materials import specular
    from tests.geometry.test_shading_normals import box_room
    calls, original = [], specular.ensure_valid_reflection

    def recording(ng, i, n):
        if len(calls) < limit:
            calls.append((ng.copy(), i.copy(), n.copy()))
        return original(ng, i, n)
    specular.ensure_valid_reflection = recording
    try:
        api.render(box_room(smooth_ball=True, ball_material=2), RenderSettings(samples=4, threads=1, backend="numpy"),
                   log=lambda m: None)
    finally:
        specular.ensure_valid_reflection = original
    return calls


def reflections_both_ways(ng, i, n):
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        return _reflections_both_ways(ng, i, n)


def _reflections_both_ways(ng, i, n):
    from engine.geometry import shading_normals_jit
    from engine.geometry.shading_normals import ensure_valid_reflection
    return ensure_valid_reflection(ng, i, n), shading_normals_jit.ensure_valid_reflection(ng, i, n)


def same_rows(a, b):
    return a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True) and np.array_equal(np.signbit(a), np.signbit(b))


def test_valid_reflection_of_recorded_hits_is_the_numpy_numbers():
    require_compiled()
    calls = recorded_reflections()
    assert len(calls) >= 4
    raised = 0
    for ng, i, n in calls:
        expected, got = reflections_both_ways(ng, i, n)
        assert same_rows(got, expected)
        raised += expected is not n
    assert raised >= 2                          # calls with hits whose normal was raised


def grazing_views(rng, m=500):
    """Unit ng, i on its side (grazing ones many), shading normals tilted up to 80 degrees off ng, and
    the edge cases: n = ng (no X axis), n = -ng, i along ng, zeros, -0.0, NaN, inf."""
    ng = rng.normal(size=(3, m))
    ng /= np.linalg.norm(ng, axis=0)
    tilt = rng.normal(size=(3, m))
    n = ng + np.tan(rng.random(m) * np.radians(80)) * (tilt - (tilt * ng).sum(axis=0) * ng)
    n /= np.linalg.norm(n, axis=0)
    i = rng.normal(size=(3, m))
    i -= (i * ng).sum(axis=0) * ng * (1.0 - 0.05 * rng.random(m))     # near the surface
    i /= np.linalg.norm(i, axis=0)
    i *= np.where((i * ng).sum(axis=0) < 0.0, -1.0, 1.0)
    n[:, 0], n[:, 1], i[:, 2] = ng[:, 0], -ng[:, 1], ng[:, 2]
    ng[:, 3], n[:, 3], i[:, 3] = (0.0, 0.0, 1.0), (1.0, -0.0, 0.0), (-1.0, 0.0, -0.0)
    n[:, 4], i[:, 5], ng[:, 6] = np.nan, np.nan, np.nan
    n[0, 7], i[1, 8], ng[2, 9] = np.inf, -np.inf, np.inf
    n[:, 10], i[:, 11] = 0.0, 0.0
    return ng, i, n


def test_valid_reflection_of_hand_made_views_is_the_numpy_numbers():
    require_compiled()
    ng, i, n = grazing_views(np.random.default_rng(21))
    expected, got = reflections_both_ways(ng, i, n)
    assert same_rows(got, expected)
    assert 50 < (expected != n).any(axis=0).sum() < len(n[0]) - 50     # raised and kept normals both
    wide = np.concatenate([n, n], axis=1)                               # strided views, as BSDFs pass them
    assert same_rows(*reflections_both_ways(ng, i, wide[:, ::2]))
    empty = np.zeros((3, 0))
    assert same_rows(*reflections_both_ways(empty, empty, empty))
    fine = n[:, expected[0] == n[0]]                                    # nothing to raise: n itself
    assert reflections_both_ways(ng[:, expected[0] == n[0]], i[:, expected[0] == n[0]], fine)[1] is fine


def test_control_valid_reflection_sees_a_last_bit():
    """One view moved by one ulp at a raised normal changes its result, and the comparison says so."""
    require_compiled()
    ng, i, n = grazing_views(np.random.default_rng(21))
    expected, _ = reflections_both_ways(ng, i, n)
    k = int(np.flatnonzero((expected != n).any(axis=0) & np.isfinite(expected).all(axis=0))[0])
    i[0, k] = np.nextafter(i[0, k], 2.0)
    _, got = reflections_both_ways(ng, i, n)
    assert np.allclose(got, expected, atol=1e-9, equal_nan=True) and not same_rows(got, expected)


def test_valid_reflection_runs_compiled_only_within_compiled_for(monkeypatch):
    require_compiled()
    from engine.geometry import shading_normals, shading_normals_jit
    calls = []
    monkeypatch.setattr(shading_normals_jit, "ensure_valid_reflection", lambda *a: calls.append(a) or a[2])
    ng, i, n = grazing_views(np.random.default_rng(2), 40)
    shading_normals.ensure_valid_reflection(ng, i, n)
    with shading_normals.compiled_for(True):
        shading_normals.ensure_valid_reflection(ng, i, n)
        with shading_normals.compiled_for(False):
            shading_normals.ensure_valid_reflection(ng, i, n)
        shading_normals.ensure_valid_reflection(ng, i, n)
    shading_normals.ensure_valid_reflection(ng, i, n)
    assert len(calls) == 2
