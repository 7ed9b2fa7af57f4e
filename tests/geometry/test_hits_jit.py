"""The compiled hit sort and triangle surfaces (engine/geometry/hits_jit.py) against the NumPy code of
engine/geometry/scene_geometry.py, on the batches of real renders of built-in scenes (recorded from
`SceneGeometry.intersect`) and on hand-made ones with every kind, forced groups and NaN coordinates."""
import numpy as np
import pytest

from engine import api
from engine.core.settings import RenderSettings
from engine.geometry import scene_geometry
from engine.geometry.scene_geometry import LIGHT, NONE, QUAD, SPHERE, TRIANGLE
from engine.materials.table import ABSORB, N_SCATTER_GROUPS, PASS_THROUGH
from engine.scene.builtin import BUILTIN_SCENES
from tests.backend_capture import require_compiled

TWIN = "engine.geometry.hits_jit"       # imported after require_compiled(): numba may be missing


def capture_batches(scene_name, limit=12):
    """[(geometry, intersect's result, nearest_hits' arguments)] of a 16 x 16, 2 spp NumPy render."""
    calls, nearest = [], scene_geometry.SceneGeometry.nearest_hits

    def recording(self, o, d, counters, *args, **kwargs):
        hits_of = self.intersect

        def intersect(*a, **k):
            out = hits_of(*a, **k)
            if len(calls) < limit:
                calls.append((self, tuple(x.copy() for x in out), args, dict(kwargs)))
            return out
        self.intersect = intersect
        try:
            return nearest(self, o, d, counters, *args, **kwargs)
        finally:
            del self.intersect
    scene_geometry.SceneGeometry.nearest_hits = recording
    try:
        api.render(BUILTIN_SCENES[scene_name]((16, 16)), RenderSettings(samples=2, threads=1, backend="numpy"),
                   log=lambda m: None)
    finally:
        scene_geometry.SceneGeometry.nearest_hits = nearest
    return calls


def hit_sets(geometry, result, args, kwargs, jit):
    """nearest_hits of the recorded batch with the NumPy code and with `jit` (None: NumPy)."""
    geometry.intersect = lambda *a, **k: result
    keep = geometry.hits_jit
    geometry.hits_jit = jit
    try:
        n = len(result[0])
        return geometry.nearest_hits(np.zeros((3, n)), np.zeros((3, n)), None, *args, **kwargs)
    finally:
        geometry.hits_jit = keep
        del geometry.intersect


def same(a, b):
    for name in ("index", "miss", "t", "kind", "prim", "u", "v", "material"):
        x, y = getattr(a, name), getattr(b, name)
        if x.dtype != y.dtype or not np.array_equal(x, y, equal_nan=True):
            return False
    return a.runs == b.runs and a.groups == b.groups


@pytest.mark.parametrize("scene", ["cornell", "many_lights", "caustic"])
def test_recorded_batches_sort_the_same(scene):
    require_compiled()
    from engine.geometry import hits_jit
    calls = capture_batches(scene)
    assert len(calls) >= 4
    for geometry, result, args, kwargs in calls:
        assert same(hit_sets(geometry, result, args, kwargs, None), hit_sets(geometry, result, args, kwargs, hits_jit))
        kind = result[1]
        tri = np.flatnonzero(kind == TRIANGLE)
        if len(tri) and geometry.has_triangles:
            prim, u, v = result[2].take(tri), result[3].take(tri), result[4].take(tri)
            reference = geometry._triangle_surface(prim, u, v)
            geometry.hits_jit = hits_jit
            try:
                compiled = geometry._triangle_surface(prim, u, v)
            finally:
                geometry.hits_jit = None
            assert all(np.array_equal(x, y) for x, y in zip(reference, compiled))


class Lights:
    count = 2


def made_up_geometry(n_materials=6):
    geometry = object.__new__(scene_geometry.SceneGeometry)
    geometry.primitive_material = np.concatenate([[0], np.arange(1, 40) % n_materials]).astype(np.int64)
    geometry.kind_base = np.array([1, 1, 11, 21, 31], np.int64)
    geometry.lights = Lights()
    geometry.hits_jit = None
    return geometry


def made_up_batch(rng, n):
    kind = rng.integers(0, 5, n).astype(np.int8)
    prim = np.where(kind == NONE, -1, rng.integers(0, 8, n)).astype(np.int64)
    t = np.where(kind == NONE, np.inf, rng.uniform(0, 5, n))
    u, v = rng.uniform(0, 1, n), rng.uniform(0, 1, n)
    return t, kind, prim, u, v


def test_made_up_batches_every_kind_and_forced_groups():
    require_compiled()
    from engine.geometry import hits_jit
    rng = np.random.default_rng(3)
    geometry = made_up_geometry()
    groups = (np.arange(6) % 4).astype(np.int8)
    for n in (0, 1, 7, 5000):
        result = made_up_batch(rng, n)
        forced = np.where(rng.random(n) < 0.2, ABSORB, -1)
        for args, kwargs in (((), {}), ((groups, N_SCATTER_GROUPS), dict(light_group=PASS_THROUGH)),
                             ((groups, N_SCATTER_GROUPS), dict(light_group=PASS_THROUGH, forced_group=forced))):
            a = hit_sets(geometry, result, args, kwargs, None)
            b = hit_sets(geometry, result, args, kwargs, hits_jit)
            assert same(a, b)
    # Control: a sort that is not stable (ties reversed) gives another order, which `same` sees.
    a = hit_sets(geometry, result, args, kwargs, None)
    assert (a.kind == SPHERE).sum() > 1 and (a.kind == LIGHT).sum() > 1
    reversed_ties = type(a)(**{**a.__dict__, "index": a.index[::-1].copy()})
    assert not same(a, reversed_ties)


def test_triangle_points_with_nan_and_large_coordinates():
    require_compiled()
    from engine.geometry import hits_jit
    rng = np.random.default_rng(5)
    geometry = made_up_geometry()
    k = 50
    tris = rng.normal(0, 1e3, (k, 3, 3))
    tris[3, 1, 2] = np.nan
    v0, v1, v2 = tris[:, 0], tris[:, 1], tris[:, 2]
    geometry.tri_v0, geometry.tri_e1, geometry.tri_e2 = (np.ascontiguousarray(a.T) for a in (v0, v1 - v0, v2 - v0))
    geometry.tri_normal = np.ascontiguousarray(rng.normal(size=(3, k)))
    geometry.tri_scale = np.abs(tris).max(axis=(1, 2))
    prim = rng.integers(0, k, 3000)
    u, v = rng.random(3000), rng.random(3000)
    reference = geometry._triangle_surface(prim, u, v)
    geometry.hits_jit = hits_jit
    compiled = geometry._triangle_surface(prim, u, v)
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(reference, compiled))
    assert np.isnan(reference[2]).any()
    # Control: a point one ulp off differs.
    assert not np.array_equal(reference[0], np.nextafter(compiled[0], np.inf))


@pytest.mark.parametrize("scene", ["cornell", "caustic"])
def test_surface_data_of_every_kind_is_the_same(scene):
    """SceneGeometry.surface with the compiled triangle and sphere points against NumPy's, on rays from
    the camera's position in every direction (walls, spheres, the lamp's quad)."""
    require_compiled()
    from engine.geometry import hits_jit
    from engine.geometry.scene_geometry import Counters, SceneGeometry
    s = BUILTIN_SCENES[scene]((8, 8))
    geometry = SceneGeometry(s, "embree")
    rng = np.random.default_rng(9)
    n = 20000
    d = rng.normal(size=(3, n))
    d /= np.sqrt((d * d).sum(axis=0))
    o = np.repeat(s.camera.matrix[:3, 3:4], n, axis=1) * 0.5
    o[:, ::10] = geometry.sphere_center[:, :1]             # and from inside a sphere: back faces
    hits = geometry.nearest_hits(o, d, Counters())
    assert {TRIANGLE, SPHERE} | ({QUAD} if scene == "cornell" else set()) <= {k for (_, k) in hits.runs}
    oh, dh = o.take(hits.index, axis=1), d.take(hits.index, axis=1)
    reference = geometry.surface(oh, dh, hits)
    geometry.hits_jit = hits_jit
    compiled = geometry.surface(oh, dh, hits)
    for name in ("point", "normal", "offset", "shading"):
        assert np.array_equal(getattr(reference, name), getattr(compiled, name)), name
    # The origins in the rays' order, read through hits.index (PathTracer.bounce's), compiled and not;
    # control: origins in another order (the sphere centres elsewhere) move some points.
    in_rays_order = geometry.surface(o, dh, hits, rays_order=True)
    for name in ("point", "normal", "offset", "facing"):
        assert np.array_equal(getattr(compiled, name), getattr(in_rays_order, name)), name
    assert not np.array_equal(compiled.point, geometry.surface(o[:, ::-1], dh, hits, rays_order=True).point)
    geometry.hits_jit = None
    assert np.array_equal(reference.point, geometry.surface(o, dh, hits, rays_order=True).point)
    geometry.hits_jit = hits_jit
    # the facing normal of PathTracer.bounce, which the one loop (hits_jit.surfaces) writes too
    assert reference.facing is None and compiled.facing is not None
    towards = np.where((dh * reference.normal).sum(axis=0) < 0.0, 1.0, -1.0)
    assert np.array_equal(compiled.facing, reference.normal * towards)
    assert (towards < 0.0).any() and (towards > 0.0).any()
    # Control: a ray one ulp longer moves some sphere points.
    geometry.hits_jit = None
    hits.t = np.nextafter(hits.t, np.inf)
    assert not np.array_equal(reference.point, geometry.surface(oh, dh, hits).point)
