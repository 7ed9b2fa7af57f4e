"""The compiled spherical-rectangle arithmetic (engine/lights/parallelograms_jit.py) against the NumPy
path of engine/lights/parallelograms.py: sample_li and pdf_li bit for bit, one light and many, near
the lights' planes (the area-sampling fallback) and far away; the light set hands its kinds the backend."""
import numpy as np

from engine.lights.parallelograms import Parallelograms
from tests.backend_capture import require_compiled

TWIN = "engine.lights.parallelograms_jit"        # imported by use_backend, not here: numba may be missing


def _lights(count, rng):
    v0 = rng.normal(size=(count, 3))
    e1 = rng.normal(size=(count, 3))
    e2 = np.cross(e1, rng.normal(size=(count, 3)))               # rectangles: e2 perpendicular to e1
    e2[-1] += 0.3 * e1[-1]                                         # and one parallelogram (area sampling)
    return v0, e1, e2


def _compare(count, seed):
    rng = np.random.default_rng(seed)
    parts = _lights(count, rng)
    a, b = Parallelograms(*parts), Parallelograms(*parts)
    b.use_backend("numba")
    assert a.compiled is None and b.compiled is not None
    m = 3000
    idx = rng.integers(0, count, m)
    x = rng.normal(size=(3, m)) * 3.0
    x[:, :100] = (a.v0.take(idx[:100], axis=1) + 0.5 * a.e1.take(idx[:100], axis=1)
                  + 1e-9 * a.normal.take(idx[:100], axis=1))        # almost in the light's plane
    u1, u2 = rng.random(m), rng.random(m)
    sa, sb = a.sample_li(x, idx, u1, u2), b.sample_li(x, idx, u1, u2)
    for name in ("point", "pdf", "radiance", "direction", "distance"):
        va, vb = getattr(sa, name, None), getattr(sb, name, None)
        if va is not None:
            assert np.array_equal(va, vb, equal_nan=True), name
    assert np.array_equal(a.pdf_li(x, idx, sa.point), b.pdf_li(x, idx, sa.point))
    anywhere = rng.normal(size=(3, m)) * 3.0                        # points off the lights: area_pdf's cases
    assert np.array_equal(a.pdf_li(x, idx, anywhere), b.pdf_li(x, idx, anywhere))
    assert np.array_equal(a.solid_angle(x, idx), b.solid_angle(x, idx), equal_nan=True)
    return a, b, x, idx, u1, u2, sa


def test_sample_and_pdf_are_bit_identical():
    require_compiled()
    _compare(1, 3)
    a, b, x, idx, u1, u2, sa = _compare(7, 4)
    # Control: the comparison sees u2 moved by 1 ulp.
    assert not np.array_equal(sa.point, b.sample_li(x, idx, u1, np.nextafter(u2, 1.0)).point)


def test_a_read_only_radiance_needs_no_compilation_after_warm_up():
    """A light radiance from np.broadcast_to (read-only) runs warm_up's signature with the bits of a
    writable one (scripts/check_warm_up.py); control: numba types the two apart."""
    require_compiled()
    from engine.lights import parallelograms_jit as pj
    pj.warm_up()
    count = len(pj._sample_blocks.signatures)
    rng = np.random.default_rng(5)
    lights = Parallelograms(*_lights(3, rng))
    x, idx, u = rng.normal(size=(3, 70)) * 3.0, np.arange(70) % 3, np.linspace(0.01, 0.99, 70)
    writable = np.array(lights.radiance, order="C")
    frozen = np.broadcast_to(writable, writable.shape)
    out = []
    for radiance in (writable, frozen):
        lights.radiance = radiance
        out.append(pj.sample_li(lights, x, idx, u, u[::-1].copy(), 1e-6, 1e-5))
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(*out))
    assert len(pj._sample_blocks.signatures) == count
    assert pj.nb.typeof(frozen) != pj.nb.typeof(writable)
