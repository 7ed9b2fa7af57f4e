"""The compiled compaction (engine/integrators/wavefront_jit.py next_rays) against the NumPy one
(engine/integrators/path_tracer.py next_rays), on the inputs of real renders of built-in scenes and
on made-up ones with NaN and huge offsets; and a render whose only compiled kernel is this one."""
import numpy as np
import pytest

from engine import api
from engine.core.settings import RenderSettings
from engine.integrators import path_tracer
from engine.scene.builtin import BUILTIN_SCENES
from tests.backend_capture import require_compiled

TWIN = "engine.integrators.wavefront_jit"       # imported after require_compiled(): numba may be missing


def capture_next_rays(scene_name, limit=8):
    calls, reference = [], path_tracer.next_rays

    def recording(*args):
        if len(calls) < limit:
            calls.append(tuple(np.array(a, copy=True) for a in args))
        return reference(*args)
    path_tracer.next_rays = recording
    try:
        api.render(BUILTIN_SCENES[scene_name]((16, 16)), RenderSettings(samples=2, threads=1, backend="numpy"),
                   log=lambda m: None)
    finally:
        path_tracer.next_rays = reference
    return calls


def same(a, b):
    return all(x.dtype == y.dtype and np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))


@pytest.mark.parametrize("scene", ["cornell", "caustic"])
def test_recorded_compactions_are_bit_identical(scene):
    require_compiled()
    from engine.integrators.wavefront_jit import next_rays
    calls = capture_next_rays(scene)
    assert len(calls) >= 4
    for args in calls:
        assert same(path_tracer.next_rays(*args), next_rays(*args))


def test_made_up_paths_with_nan_and_both_sides():
    require_compiled()
    from engine.integrators.wavefront_jit import next_rays
    rng = np.random.default_rng(4)
    n = 5000
    point, facing, new_d, beta = (rng.normal(0, 1e3, (3, n)) for _ in range(4))
    point[1, 17] = np.nan
    side, offset = np.where(rng.random(n) < 0.5, -1.0, 1.0), 10.0 ** rng.uniform(-12, 3, n)
    keep = np.sort(rng.choice(n, 3000, replace=False))
    a, b = path_tracer.next_rays(keep, point, side, offset, facing, new_d, beta), \
        next_rays(keep, point, side, offset, facing, new_d, beta)
    assert same(a, b)
    # Controls: an origin one ulp off, or moved by the offset without the side, is not the same.
    assert not same(a, (np.nextafter(a[0], np.inf),) + a[1:])
    unsided = point.take(keep, axis=1) + offset.take(keep) * facing.take(keep, axis=1)
    assert not same(a, (unsided,) + a[1:])


def test_a_render_with_the_compiled_compaction_alone_is_the_same():
    require_compiled()
    from engine.integrators import wavefront_jit
    from engine.rendering import session
    scene = BUILTIN_SCENES["caustic"]((24, 24))
    settings = RenderSettings(samples=4, threads=1, backend="numpy")
    reference = api.render(scene, settings, log=lambda m: None).image
    original = session.PathTracer.__init__

    def with_twin(self, *args, **kwargs):
        original(self, *args, **kwargs)
        self.wavefront_jit = wavefront_jit
    session.PathTracer.__init__ = with_twin
    try:
        compiled = api.render(BUILTIN_SCENES["caustic"]((24, 24)), settings, log=lambda m: None).image
    finally:
        session.PathTracer.__init__ = original
    assert np.array_equal(reference, compiled)
