"""engine/lights/trig.py's asin and sincos (+ - * / sqrt only) against the C library's (Python's math),
and their numba twins (engine/lights/parallelograms_jit.py `_asin`, `_sincos`) against them bit for bit,
on the rectangle's arguments and the edges of each range; controls: a wrong constant or a wrong
quadrant is seen."""
import math

import numpy as np

from engine.lights import trig
from tests.backend_capture import require_compiled


def _ulps(a, reference):
    return np.abs(a - reference) / np.spacing(np.abs(reference))


def _asin_arguments():
    rng = np.random.default_rng(1)
    edges = [0.0, -0.0, 1.0, -1.0, 0.5, -0.5, np.nextafter(0.5, 0.0), 0.975, np.nextafter(0.975, 0.0), 1e-300, 5e-324]
    return np.concatenate([rng.uniform(-1.0, 1.0, 20000), rng.uniform(0.97, 1.0, 5000), edges])


def _angles():
    rng = np.random.default_rng(2)
    return np.concatenate([rng.uniform(-3.3, 3.3, 20000), rng.uniform(-1e-3, 1e-3, 2000),
                           [0.0, -0.0, math.pi / 4, -math.pi / 4, math.pi / 2, 3.0, -3.0, 1e-300]])


def test_asin_within_an_ulp_of_the_c_library():
    a = _asin_arguments()
    reference = np.array([math.asin(v) for v in a])
    got = trig.asin(a)
    assert np.array_equal(np.signbit(got), np.signbit(reference))
    assert _ulps(got[reference != 0.0], reference[reference != 0.0]).max() <= 1.0
    assert np.isnan(trig.asin(np.array([np.nan]))).all()


def test_sincos_within_an_ulp_of_the_c_library():
    x = _angles()
    sin, cos = trig.sincos(x)
    for got, reference in ((sin, np.array([math.sin(v) for v in x])), (cos, np.array([math.cos(v) for v in x]))):
        away = np.abs(reference) > 1e-6          # near the zeros at k pi / 2 (k != 0) the error is absolute:
        assert _ulps(got[away], reference[away]).max() <= 1.0
        assert np.abs(got - reference).max() <= 1.2e-16    # pi / 2 in two parts, 86 bits
    assert np.isnan(trig.sincos(np.array([np.nan, np.inf]))).all()


def test_controls_see_a_wrong_constant_and_a_wrong_quadrant(monkeypatch):
    x = _angles()
    reference = np.array([math.sin(v) for v in x])
    monkeypatch.setattr(trig, "S3", trig.S3 * (1.0 + 1e-9))
    assert _ulps(trig.sincos(x)[0][np.abs(reference) > 1e-6], reference[np.abs(reference) > 1e-6]).max() > 1.0
    monkeypatch.undo()
    monkeypatch.setattr(trig, "PIO2_1", trig.PIO2_1 + 1e-12)      # a quadrant's reduction off
    cos = np.array([math.cos(v) for v in x])
    assert _ulps(trig.sincos(x)[1][np.abs(cos) > 1e-6], cos[np.abs(cos) > 1e-6]).max() > 1.0


def test_numba_twins_are_bit_identical():
    require_compiled()
    import numba
    from engine.lights import parallelograms_jit as twin

    @numba.njit(error_model="numpy")          # as the kernels: 0 / 0 is NaN, not an exception
    def run(a, x, g, s, c):
        for i in range(a.shape[0]):
            g[i] = twin._asin(a[i])
        for i in range(x.shape[0]):
            s[i], c[i] = twin._sincos(x[i])

    a, x = np.append(_asin_arguments(), np.nan), np.append(_angles(), [np.nan, np.inf, 40.0])
    g, s, c = np.empty_like(a), np.empty_like(x), np.empty_like(x)
    run(a, x, g, s, c)
    assert np.array_equal(g, trig.asin(a), equal_nan=True)
    sin, cos = trig.sincos(x)
    assert np.array_equal(s, sin, equal_nan=True) and np.array_equal(c, cos, equal_nan=True)
    assert not np.array_equal(g[:-1], np.arcsin(a[:-1]))            # control: not NumPy's arcsin
