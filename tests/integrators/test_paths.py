"""engine/integrators/path_tracer.py Paths: `take` with room after the taken paths and `put` into it
(how the camera paths join the wavefront without a concatenation of its arrays), on both backends'
gathers, against NumPy's take and concatenate on paths with every field set; control: the put at the
wrong place is caught."""
import numpy as np
import pytest

from engine.integrators.path_tracer import Paths, VECTOR_FIELDS
from engine.materials.media import MEDIUM_STACK_DEPTH
from tests.backend_capture import require_compiled

DTYPES = {"pixel": np.int64, "sample": np.int64, "prev_delta": np.bool_, "ray_kind": np.int8, "bounce": np.int32,
          "depth": np.int64, "f_open": np.bool_, "counts": np.int32, "after_diffuse": np.bool_, "lobe": np.int8,
          "lobe_at": np.int32, "caustic": np.int8}


def random_paths(n, rng):
    """Paths of n with every field: NaN, inf and -0.0 in the float ones."""
    values = {}
    for name in Paths.__dataclass_fields__:
        dtype = DTYPES.get(name, np.float64)
        shape = ((4 if name == "counts" else 3, n) if name in VECTOR_FIELDS else (n, MEDIUM_STACK_DEPTH) if name == "media" else (n,))
        a = rng.integers(-100, 100, shape).astype(dtype) if dtype != np.float64 else rng.normal(size=shape)
        if dtype == np.float64 and a.size > 3:
            a.reshape(-1)[:3] = (np.nan, np.inf, -0.0)
        values[name] = a
    return Paths(**values)


def axis_of(name):
    return 1 if name in VECTOR_FIELDS else 0


def same_bits(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def take_jit(compiled):
    """Paths.take's jit: wavefront_jit's compiled gathers, or None (NumPy's)."""
    if not compiled:
        return None
    require_compiled()
    from engine.integrators import wavefront_jit
    return wavefront_jit


@pytest.mark.parametrize("compiled", [False, True])
def test_take_with_room_then_put_is_take_then_concatenate(compiled):
    rng = np.random.default_rng(4)
    jit = take_jit(compiled)
    p, joining = random_paths(500, rng), random_paths(37, rng)
    for index in (np.flatnonzero(rng.random(500) < 0.6), np.arange(0, dtype=np.int64), np.arange(500)):
        for room in (0, 37):
            taken = p.take(index, replaced=("o",), jit=jit, room=room)
            assert taken.o is None
            taken.o = np.concatenate([p.o.take(index, axis=1), np.zeros((3, room))], axis=1)
            if room:
                taken.put(len(index), joining)
            for name in Paths.__dataclass_fields__:
                axis = axis_of(name)
                parts = [getattr(p, name).take(index, axis=axis)] + ([getattr(joining, name)] if room else [])
                assert same_bits(getattr(taken, name), np.concatenate(parts, axis=axis)), (name, room)


def test_control_a_put_one_place_late_is_caught():
    rng = np.random.default_rng(5)
    p, joining = random_paths(100, rng), random_paths(10, rng)
    index = np.arange(50)
    taken = p.take(index, room=11)
    taken.put(len(index) + 1, joining)
    assert not same_bits(taken.radiance[:, :60], np.concatenate([p.radiance[:, :50], joining.radiance], axis=1))


def test_camera_paths_put_in_the_room_are_paths_start():
    """put_start writes what Paths.start makes, every optional field on, after the taken paths; control:
    another starting value is caught."""
    from types import SimpleNamespace
    rng = np.random.default_rng(6)
    light_paths = SimpleNamespace(bounce_limits=True, caustics=True, filter_glossy=1.0)
    starting = Paths.starting(True, True, True, light_paths, True, True, True)
    assert set(starting) == set(Paths.__dataclass_fields__) - {"pixel", "sample", "o", "d"}
    p = random_paths(60, rng)
    rays = (rng.integers(0, 9, 25), rng.integers(0, 9, 25), rng.normal(size=(3, 25)), rng.normal(size=(3, 25)))
    new = Paths.start(*rays, starting)
    index = np.flatnonzero(rng.random(60) < 0.5)
    taken = p.take(index, room=25)
    taken.put_start(len(index), *rays, starting)
    for name in Paths.__dataclass_fields__:
        axis = axis_of(name)
        expected = np.concatenate([getattr(p, name).take(index, axis=axis), getattr(new, name)], axis=axis)
        assert same_bits(getattr(taken, name), expected), name
    wrong = dict(starting, beta=(np.nextafter(1.0, 2.0), np.float64))
    taken.put_start(len(index), *rays, wrong)
    assert not same_bits(taken.beta[:, len(index):], new.beta)


def test_camera_paths_start_as_a_path_tracer_starts_them():
    """Paths.starting's values, every option on, are what a camera path starts with (the report's
    throughput 1, no radiance yet; the camera ray counts as a delta vertex for MIS; the MIS vertex zero,
    its BSDF pdf 1; media of index 1 in an empty stack; no bounce counted; no diffuse bounce yet; no
    glossy filter bound (inf); the camera chain of the photon caustics; the deferred roulette's survival
    1; no lobe yet (-1) set at bounce 0): pinned value by value, so a wrong one in the table that
    Paths.start and put_start share is caught."""
    from types import SimpleNamespace
    light_paths = SimpleNamespace(bounce_limits=True, caustics=True, filter_glossy=1.0)
    starting = Paths.starting(True, True, True, light_paths, True, True, True)
    f64 = np.float64
    expected = {"beta": (1.0, f64), "radiance": (0.0, f64), "prev_delta": (True, np.bool_), "ray_kind": (0, np.int8),
                "bounce": (0, np.int32), "prev_p": (0.0, f64), "prev_n": (0.0, f64), "prev_bsdf_pdf": (1.0, f64),
                "media": (1.0, f64), "depth": (0, np.int64), "f_thru": (1.0, f64), "f_open": (True, np.bool_),
                "counts": (0, np.int32), "after_diffuse": (False, np.bool_), "min_pdf": (np.inf, f64),
                "caustic": (0, np.int8), "rr_after": (1.0, f64), "lobe": (-1, np.int8), "lobe_at": (0, np.int32)}
    assert {k: (v, np.dtype(t)) for k, (v, t) in starting.items()} == {k: (v, np.dtype(t)) for k, (v, t) in expected.items()}
    assert Paths.starting(False, False) == {k: expected[k] for k in ("beta", "radiance", "prev_delta", "ray_kind", "bounce")}
