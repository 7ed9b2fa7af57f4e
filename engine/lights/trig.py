"""The arcsine, sine and cosine of the rectangle lights' solid-angle sampling (engine/lights/parallelograms.py)
written with +, -, *, / and sqrt only, so that its numba twin (engine/lights/parallelograms_jit.py
`_asin`, `_sincos`) repeats them bit for bit in loops LLVM vectorises.  NumPy's vectorised arcsin and
the C library's asin differ in the last bit on AVX-512 machines, and the C library's cos and sin are
scalar calls in a compiled loop (docs/performance.md "Compiled kernels"); these are neither.

The formulas are fdlibm's (Sun Microsystems, 1993; as in FreeBSD's msun and musl): `asin` is e_asin.c's
rational approximation on [0, 0.5] and its half-angle form on [0.5, 1] (the high part f of sqrt(z)
split off by Veltkamp's product with 2^27 + 1 instead of clearing its low word); `sincos` reduces x by
the nearest multiple k of pi/2 (k by adding and subtracting 1.5 * 2^52, pi/2 in two parts as fdlibm's
pio2_1, pio2_1t; exact for |k| < 2^20) and evaluates the __kernel_sin and __kernel_cos polynomials on
[-pi/4, pi/4].  Error (tests/lights/test_trig.py): asin within one unit in the last place of the C
library's on [-1, 1]; sin and cos within one unit on [-3.3, 3.3] except near their zeros at k pi/2
(k != 0), where it is absolute, below 1e-25 (pi/2 carries 86 bits), against the result's rounding of ~1e-16.
NaN gives NaN; arguments outside [-1, 1] (asin) are not expected (the callers clip them).

The constants and the order of the operations follow fdlibm, whose notice reads:
    Copyright (C) 1993 by Sun Microsystems, Inc. All rights reserved.
    Developed at SunSoft, a Sun Microsystems, Inc. business.
    Permission to use, copy, modify, and distribute this software is freely granted, provided that
    this notice is preserved.
"""
from __future__ import annotations

import numpy as np

# asin: fdlibm e_asin.c
PIO2_HI, PIO2_LO, PIO4_HI = 1.57079632679489655800e+00, 6.12323399573676603587e-17, 7.85398163397448278999e-01
PS0, PS1, PS2 = 1.66666666666666657415e-01, -3.25565818622400915405e-01, 2.01212532134862925881e-01
PS3, PS4, PS5 = -4.00555345006794114027e-02, 7.91534994289814532176e-04, 3.47933107596021167570e-05
QS1, QS2 = -2.40339491173441421878e+00, 2.02094576023350569471e+00
QS3, QS4 = -6.88283971605453293030e-01, 7.70381505559019352791e-02
SPLIT = 134217729.0                      # 2^27 + 1: Veltkamp's split of a double into 26 + 26 bits
# sin, cos: fdlibm k_sin.c, k_cos.c, and e_rem_pio2.c's first two parts of pi/2
S1, S2, S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
S4, S5, S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
C1, C2, C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
C4, C5, C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11
INVPIO2 = 6.36619772367581382433e-01     # 2 / pi
PIO2_1, PIO2_1T = 1.57079632673412561417e+00, 6.07710050650619224932e-11     # pi/2 = PIO2_1 + PIO2_1T (33 bits + tail)
ROUND = 6755399441055744.0               # 1.5 * 2^52: (v + ROUND) - ROUND is v rounded to an integer


def _r(t):
    """fdlibm's R(t) = p / q for asin."""
    p = t * (PS0 + t * (PS1 + t * (PS2 + t * (PS3 + t * (PS4 + t * PS5)))))
    q = 1.0 + t * (QS1 + t * (QS2 + t * (QS3 + t * QS4)))
    return p / q


def asin(a):
    """arcsin of a (an array in [-1, 1]), e_asin.c's three ranges, each computed everywhere and selected
    (one R for all three)."""
    a = np.asarray(a, dtype=np.float64)
    ax = np.abs(a)
    with np.errstate(divide="ignore", invalid="ignore"):   # the branches not taken may divide 0 by 0
        t = (1.0 - ax) * 0.5                               # |a| >= 0.5: asin = pi/2 - 2 asin(sqrt(t))
        r = _r(np.where(ax < 0.5, a * a, t))               # R of a^2 (|a| < 0.5) or of t
        small = a + a * r                                  # |a| < 0.5
        s = np.sqrt(t)
        near_one = PIO2_HI - (2.0 * (s + s * r) - PIO2_LO)     # |a| >= 0.975
        c = s * SPLIT
        f = c - (c - s)                                    # the high 26 bits of s: f * f is exact
        c = (t - f * f) / (s + f)                          # s = f + c
        middle = PIO4_HI - ((2.0 * s * r - (PIO2_LO - 2.0 * c)) - (PIO4_HI - 2.0 * f))
    big = np.where(ax >= 0.975, near_one, middle)
    return np.where(ax < 0.5, small, np.copysign(big, a))


def _kernel_sin(r, z):
    return r + z * r * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))))


def _kernel_cos(z):
    hz = 0.5 * z
    w = 1.0 - hz
    return w + (((1.0 - w) - hz) + z * (z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))))))


def sincos(x):
    """(sin x, cos x) of an array x (|x| < 2^20 pi/2): the quadrant by k, the kernels on the rest."""
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(invalid="ignore"):                    # NaN and inf give NaN
        k = (x * INVPIO2 + ROUND) - ROUND
        r = (x - k * PIO2_1) - k * PIO2_1T
        z = r * r
        s, c = _kernel_sin(r, z), _kernel_cos(z)
    quadrant = np.where(np.isfinite(k), k, 0.0).astype(np.int64) & 3
    odd = (quadrant & 1) == 1                              # quadrants 1, 3: sin and cos swap
    sin = np.where(odd, c, s)
    cos = np.where(odd, s, c)
    sin = np.where(quadrant >= 2, -sin, sin)               # quadrants 2, 3: sin negated
    cos = np.where((quadrant == 1) | (quadrant == 2), -cos, cos)   # quadrants 1, 2: cos negated
    return sin, cos
