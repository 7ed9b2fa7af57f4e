"""engine/geometry/accel/embree_jit.py: Embree called by the compiled loop answers every ray as
embreex's EmbreeScene.run does (EmbreeAccelerator's NumPy path), and folds them into the nearest
hits so far as SceneGeometry's NumPy lines do (nearest_rows), on the rays of real renders
(recorded from SceneGeometry) and on random rays with finite and infinite tmax."""
import numpy as np
import pytest

from engine import api
from engine.core.settings import RenderSettings
from engine.geometry import scene_geometry
from engine.geometry.accel import embree_buffers
from engine.geometry.accel.embree import EmbreeAccelerator
from engine.scene.builtin import BUILTIN_SCENES
from tests.backend_capture import require_compiled


def compiled():
    require_compiled()
    from engine.geometry.accel import embree_jit
    if not embree_jit.bind():
        pytest.skip("Embree's library is not reachable through embree_buffers")
    return embree_jit


def capture_rays(scene_name, limit=16):
    """[(accelerator, query, o, d, tmax)] of a 16 x 16, 2 spp NumPy render's triangle queries."""
    calls = []
    intersect, occluded = scene_geometry.SceneGeometry.intersect, scene_geometry.SceneGeometry.occluded

    def keep(self, query, o, d, tmax):
        if len(calls) < limit and self.has_triangles:
            calls.append((self.accelerator, query, o.copy(), d.copy(),
                          np.full(o.shape[1], np.inf) if tmax is None else np.array(tmax, np.float64)))

    def rec_intersect(self, o, d, counters, tmax=None, ray_kind=None):
        keep(self, "intersect", o, d, tmax)
        return intersect(self, o, d, counters, tmax, ray_kind)

    def rec_occluded(self, o, d, tmax, counters):
        keep(self, "occluded", o, d, tmax)
        return occluded(self, o, d, tmax, counters)
    scene_geometry.SceneGeometry.intersect, scene_geometry.SceneGeometry.occluded = rec_intersect, rec_occluded
    try:
        api.render(BUILTIN_SCENES[scene_name]((16, 16)), RenderSettings(samples=2, threads=1, backend="numpy"),
                   log=lambda m: None)
    finally:
        scene_geometry.SceneGeometry.intersect, scene_geometry.SceneGeometry.occluded = intersect, occluded
    return calls


def same_hits(a, b):
    """The same t and prim everywhere, the same u, v at the hits (a miss's u, v: embree_jit.py)."""
    hit = a[1] >= 0
    return (all(x.dtype == y.dtype for x, y in zip(a, b)) and np.array_equal(a[0], b[0])
            and np.array_equal(a[1], b[1]) and np.array_equal(a[2][hit], b[2][hit]) and np.array_equal(a[3][hit], b[3][hit]))


def answers(accelerator, query, o, d, tmax, jit):
    return getattr(accelerator, f"{query}_rows")(o, d, tmax.copy(), jit)


def same_nearest(a, b):
    """nearest_rows' (t, kind, prim, u, v): the same everywhere but u, v, the same at triangle hits."""
    tri = a[1] == 1
    return (all(x.dtype == y.dtype for x, y in zip(a, b)) and all(np.array_equal(x, y) for x, y in zip(a[:3], b[:3]))
            and np.array_equal(a[3][tri], b[3][tri]) and np.array_equal(a[4][tri], b[4][tri]))


@pytest.mark.parametrize("scene", ["cornell", "many_lights", "caustic"])
def test_recorded_rays_hit_the_same(scene):
    jit = compiled()
    calls = capture_rays(scene)
    assert {c[1] for c in calls} == {"intersect", "occluded"}
    for accelerator, query, o, d, tmax in calls:
        ref, ours = answers(accelerator, query, o, d, tmax, None), answers(accelerator, query, o, d, tmax, jit)
        if query == "intersect":
            assert same_hits(ref, ours)
            assert same_nearest(answers(accelerator, "nearest", o, d, tmax, None),
                                answers(accelerator, "nearest", o, d, tmax, jit))
        else:
            assert ours.dtype == ref.dtype and np.array_equal(ours, ref)


def test_random_rays_and_the_control():
    jit = compiled()
    rng = np.random.default_rng(5)
    centres = rng.uniform(-1, 1, (2000, 1, 3))
    accelerator = EmbreeAccelerator(centres + rng.normal(0, 0.1, (2000, 3, 3)))
    n = 20000
    o, d = rng.uniform(-2, 2, (3, n)), rng.normal(0, 1, (3, n))
    tmax = np.where(rng.random(n) < 0.5, np.inf, rng.uniform(0.1, 3.0, n))
    ref = answers(accelerator, "intersect", o, d, tmax, None)
    assert (ref[1] >= 0).sum() > 2000 and np.isfinite(tmax).sum() > 5000
    assert same_hits(ref, answers(accelerator, "intersect", o, d, tmax, jit))
    nearest = answers(accelerator, "nearest", o, d, tmax, None)
    assert 0 < (nearest[1] == 1).sum() < (ref[1] >= 0).sum() + 1
    assert same_nearest(nearest, answers(accelerator, "nearest", o, d, tmax, jit))
    blocked = answers(accelerator, "occluded", o, d, tmax, None)
    assert 0 < blocked.sum() < n and np.array_equal(blocked, answers(accelerator, "occluded", o, d, tmax, jit))
    # control: origins one float32 step away (what a float64 rounding of its own would give) change answers
    moved = np.nextafter(o.astype(np.float32), np.float32(np.inf)).astype(np.float64)
    assert not same_hits(ref, answers(accelerator, "intersect", moved, d, tmax, jit))
    assert not same_nearest(nearest, answers(accelerator, "nearest", moved, d, tmax, jit))
    assert embree_buffers.scene_handle(accelerator.scene) == accelerator.handle()
