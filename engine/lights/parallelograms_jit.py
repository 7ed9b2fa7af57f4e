"""engine/lights/parallelograms.py's spherical-rectangle sampling compiled with numba: per block of
BLOCK receivers, the local frame of each light seen from x and its edge-plane normals (`_frame`), the
four arcsines, the solid angle and the cos and sin of the angle u1 draws (engine/lights/trig.py's
asin and sincos, + - * / and sqrt only), the spherical point (`_spherical_point`), 1 / Omega or the
area fallback, and the direction and distance (`finite_sample`), all in one call: the same float64
operations in the same order as the NumPy path, so the same points and densities bit for bit
(tests/lights/test_parallelograms_jit.py).

Layout: each block's inputs are copied into one flat lane array (row k of receiver b at
k * BLOCK + b), whose loops (`_lane_frame`, `_lane_angles`, `_lane_spherical`, `_lane_directions`)
LLVM vectorises: every branch a select, rows at constant offsets (a loop over rows of several arrays
at runtime strides needs more runtime overlap checks than LLVM allows; docs/performance.md "Wavefront
speed").  The area fallback (near a light's plane, parallelograms) runs per receiver where it applies.
Imported only through engine/core/backend.py's choice (it imports numba)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from ..core.kernel_inputs import contiguous, fitted, read_only
from . import trig

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)
inline = nb.njit(cache=True, error_model="numpy", nogil=True, inline="always")     # inlined into its callers

BIG = np.finfo(np.float64).max          # what np.nan_to_num makes of +inf

BLOCK = 64                              # receivers of a block in the lanes
# Rows of the lane array.  Inputs: the receiver, its light's corner, axes, edge lengths, centre and
# rectangle flag, the uniforms (u1, u2).  The frame: the flipped z axis, f (x0, y0, x1, y1, z0, e0, e2),
# the four arcsine arguments, |centre - x|.  The angles: Omega, cos and sin of au.  Outputs: point,
# direction, distance, pdf and `use` (1.0 where the spherical point holds).
LX, LV0, LA1, LA2, LA3, LLEN1, LLEN2, LC, LRECT, LU1, LU2 = 0, 3, 6, 9, 12, 15, 16, 17, 20, 21, 22
LAZ, LF, LARGS, LCD = 23, 26, 33, 37
LOMEGA, LCOS, LSIN = 38, 39, 40
LPOINT, LDIR, LDIST, LPDF, LUSE = 41, 44, 47, 48, 49
ROWS = 50


@inline
def _clip_select(v, lo, hi):
    """np.clip(v, lo, hi) as NumPy's clip loop (min(max(v, lo), hi) by > and <, NaN kept), as selects."""
    m = v if v > lo else lo
    r = m if m < hi else hi
    r = m if m != m else r
    return v if v != v else r


@inline
def _r(t):
    """trig._r."""
    p = t * (trig.PS0 + t * (trig.PS1 + t * (trig.PS2 + t * (trig.PS3 + t * (trig.PS4 + t * trig.PS5)))))
    q = 1.0 + t * (trig.QS1 + t * (trig.QS2 + t * (trig.QS3 + t * trig.QS4)))
    return p / q


@inline
def _asin(a):
    """trig.asin of one number: the same operations, the same selects."""
    ax = np.abs(a)
    t = (1.0 - ax) * 0.5
    r = _r(a * a if ax < 0.5 else t)
    small = a + a * r
    s = np.sqrt(t)
    near_one = trig.PIO2_HI - (2.0 * (s + s * r) - trig.PIO2_LO)
    c = s * trig.SPLIT
    f = c - (c - s)
    c = (t - f * f) / (s + f)
    middle = trig.PIO4_HI - ((2.0 * s * r - (trig.PIO2_LO - 2.0 * c)) - (trig.PIO4_HI - 2.0 * f))
    big = near_one if ax >= 0.975 else middle
    return small if ax < 0.5 else np.copysign(big, a)


@inline
def _sincos(x):
    """trig.sincos of one number."""
    k = (x * trig.INVPIO2 + trig.ROUND) - trig.ROUND
    r = (x - k * trig.PIO2_1) - k * trig.PIO2_1T
    z = r * r
    s = r + z * r * (trig.S1 + z * (trig.S2 + z * (trig.S3 + z * (trig.S4 + z * (trig.S5 + z * trig.S6)))))
    hz = 0.5 * z
    w = 1.0 - hz
    c = w + (((1.0 - w) - hz) + z * (z * (trig.C1 + z * (trig.C2 + z * (trig.C3 + z * (trig.C4 + z * (
        trig.C5 + z * trig.C6)))))))
    quadrant = np.int64(k if k - k == 0.0 else 0.0) & 3
    odd = (quadrant & 1) == 1
    sin = c if odd else s
    cos = s if odd else c
    sin = -sin if quadrant >= 2 else sin
    cos = -cos if (quadrant == 1) | (quadrant == 2) else cos
    return sin, cos


@jit
def _lane_frame(lane, size):
    """parallelograms.py _frame up to the arcsines' arguments for lanes b < size."""
    B = BLOCK
    for b in range(size):
        x0_, x1_, x2_ = lane[LX * B + b], lane[(LX + 1) * B + b], lane[(LX + 2) * B + b]
        r0, r1, r2 = lane[LV0 * B + b] - x0_, lane[(LV0 + 1) * B + b] - x1_, lane[(LV0 + 2) * B + b] - x2_
        a0, a1, a2 = lane[LA3 * B + b], lane[(LA3 + 1) * B + b], lane[(LA3 + 2) * B + b]
        z0 = r0 * a0 + r1 * a1 + r2 * a2
        flip = -1.0 if z0 > 0.0 else 1.0
        lane[LAZ * B + b], lane[(LAZ + 1) * B + b], lane[(LAZ + 2) * B + b] = a0 * flip, a1 * flip, a2 * flip
        z0 = z0 * flip
        x0 = r0 * lane[LA1 * B + b] + r1 * lane[(LA1 + 1) * B + b] + r2 * lane[(LA1 + 2) * B + b]
        y0 = r0 * lane[LA2 * B + b] + r1 * lane[(LA2 + 1) * B + b] + r2 * lane[(LA2 + 2) * B + b]
        x1, y1 = x0 + lane[LLEN1 * B + b], y0 + lane[LLEN2 * B + b]
        z2 = z0 * z0
        e0 = -y0 / np.sqrt(y0 * y0 + z2)
        e1 = x1 / np.sqrt(x1 * x1 + z2)
        e2 = y1 / np.sqrt(y1 * y1 + z2)
        e3 = -x0 / np.sqrt(x0 * x0 + z2)
        lane[LARGS * B + b] = _clip_select(-e0 * e1, -1.0, 1.0)
        lane[(LARGS + 1) * B + b] = _clip_select(-e1 * e2, -1.0, 1.0)
        lane[(LARGS + 2) * B + b] = _clip_select(-e2 * e3, -1.0, 1.0)
        lane[(LARGS + 3) * B + b] = _clip_select(-e3 * e0, -1.0, 1.0)
        lane[LF * B + b], lane[(LF + 1) * B + b], lane[(LF + 2) * B + b], lane[(LF + 3) * B + b] = x0, y0, x1, y1
        lane[(LF + 4) * B + b], lane[(LF + 5) * B + b], lane[(LF + 6) * B + b] = z0, e0, e2
        c0, c1, c2 = lane[LC * B + b] - x0_, lane[(LC + 1) * B + b] - x1_, lane[(LC + 2) * B + b] - x2_
        lane[LCD * B + b] = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)


@jit
def _lane_angles(lane, size):
    """The four arcsines, Omega = -(g0 + g1 + g2 + g3) and (sin, cos) of au = u1 Omega + (g2 + g3)
    (parallelograms.py _frame and _spherical_point) for lanes b < size."""
    B = BLOCK
    for b in range(size):
        g0, g1 = _asin(lane[LARGS * B + b]), _asin(lane[(LARGS + 1) * B + b])
        g2, g3 = _asin(lane[(LARGS + 2) * B + b]), _asin(lane[(LARGS + 3) * B + b])
        omega = -(g0 + g1 + g2 + g3)
        sin, cos = _sincos(lane[LU1 * B + b] * omega + (g2 + g3))
        lane[LOMEGA * B + b], lane[LCOS * B + b], lane[LSIN * B + b] = omega, cos, sin


@jit
def _lane_omega(lane, size):
    """Omega alone (_lane_angles without the drawn angle: pdf_li)."""
    B = BLOCK
    for b in range(size):
        g0, g1 = _asin(lane[LARGS * B + b]), _asin(lane[(LARGS + 1) * B + b])
        g2, g3 = _asin(lane[(LARGS + 2) * B + b]), _asin(lane[(LARGS + 3) * B + b])
        lane[LOMEGA * B + b] = -(g0 + g1 + g2 + g3)


@jit
def _lane_spherical(lane, size, omega_min, grazing):
    """sample_li's `use` predicate, spherical point (_spherical_point after the cos and sin) and
    1 / Omega for lanes b < size, every receiver's (the area fallback is _sample_blocks')."""
    B = BLOCK
    for b in range(size):
        x0, x1, x2 = lane[LX * B + b], lane[(LX + 1) * B + b], lane[(LX + 2) * B + b]
        fx0, fy0 = lane[LF * B + b], lane[(LF + 1) * B + b]
        fx1, fy1 = lane[(LF + 2) * B + b], lane[(LF + 3) * B + b]
        z0, e0, e2 = lane[(LF + 4) * B + b], lane[(LF + 5) * B + b], lane[(LF + 6) * B + b]
        omega, cd, u2 = lane[LOMEGA * B + b], lane[LCD * B + b], lane[LU2 * B + b]
        use = (lane[LRECT * B + b] != 0.0) & (omega >= omega_min) & (omega - omega == 0.0) & (-z0 >= grazing * cd)
        fu = (lane[LCOS * B + b] * e0 + e2) / lane[LSIN * B + b]
        cu = _clip_select(np.copysign(1.0, fu) / np.sqrt(fu * fu + e0 * e0), -1.0, 1.0)
        s = np.sqrt(1.0 - cu * cu)
        s = s if (s >= 1e-300 or s != s) else 1e-300    # np.maximum(s, 1e-300)
        xu = _clip_select(-(cu * z0) / s, fx0, fx1)
        d2 = xu * xu + z0 * z0
        h0 = fy0 / np.sqrt(d2 + fy0 * fy0)
        h1 = fy1 / np.sqrt(d2 + fy1 * fy1)
        hv = h0 + u2 * (h1 - h0)
        yv = hv * np.sqrt(d2) / np.sqrt(1.0 - hv * hv)
        yv = yv if hv * hv < 1.0 - 1e-12 else fy1
        yv = 0.0 if yv != yv else (BIG if yv == np.inf else (-BIG if yv == -np.inf else yv))   # np.nan_to_num
        yv = _clip_select(yv, fy0, fy1)
        lane[LPOINT * B + b] = x0 + xu * lane[LA1 * B + b] + yv * lane[LA2 * B + b] + z0 * lane[LAZ * B + b]
        lane[(LPOINT + 1) * B + b] = (x1 + xu * lane[(LA1 + 1) * B + b] + yv * lane[(LA2 + 1) * B + b]
                                      + z0 * lane[(LAZ + 1) * B + b])
        lane[(LPOINT + 2) * B + b] = (x2 + xu * lane[(LA1 + 2) * B + b] + yv * lane[(LA2 + 2) * B + b]
                                      + z0 * lane[(LAZ + 2) * B + b])
        lane[LPDF * B + b] = 1.0 / omega
        lane[LUSE * B + b] = 1.0 if use else 0.0


@jit
def _lane_directions(lane, size):
    """finite_sample's distance and direction of each lane's point."""
    B = BLOCK
    for b in range(size):
        w0 = lane[LPOINT * B + b] - lane[LX * B + b]
        w1 = lane[(LPOINT + 1) * B + b] - lane[(LX + 1) * B + b]
        w2 = lane[(LPOINT + 2) * B + b] - lane[(LX + 2) * B + b]
        dist = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        lane[LDIST * B + b] = dist
        lane[LDIR * B + b], lane[(LDIR + 1) * B + b], lane[(LDIR + 2) * B + b] = w0 / dist, w1 / dist, w2 / dist


@jit
def _fill_light(lane, b, j, axis1, axis2, axis3, v0, len1, len2, center, rectangle):
    B = BLOCK
    for c in range(3):
        lane[(LV0 + c) * B + b], lane[(LA1 + c) * B + b] = v0[c, j], axis1[c, j]
        lane[(LA2 + c) * B + b], lane[(LA3 + c) * B + b] = axis2[c, j], axis3[c, j]
        lane[(LC + c) * B + b] = center[c, j]
    lane[LLEN1 * B + b], lane[LLEN2 * B + b] = len1[j], len2[j]
    lane[LRECT * B + b] = 1.0 if rectangle[j] else 0.0


@jit
def _fill_block(lane, start, size, x, idx, one, axis1, axis2, axis3, v0, len1, len2, center, rectangle):
    """A block's receivers and (unless one light for all, filled once) lights into the lanes, row by row."""
    B = BLOCK
    if not one:
        for b in range(size):
            _fill_light(lane, b, idx[start + b], axis1, axis2, axis3, v0, len1, len2, center, rectangle)
    for c in range(3):
        for b in range(size):
            lane[(LX + c) * B + b] = x[c, start + b]


@jit
def _area_pdf(x, i, point, j, normal, area):
    """parallelograms.py area_pdf of receiver i (x) and `point` on light j."""
    w0, w1, w2 = point[0] - x[0, i], point[1] - x[1, i], point[2] - x[2, i]
    d2 = w0 * w0 + w1 * w1 + w2 * w2
    cos_y = np.abs(normal[0, j] * w0 + normal[1, j] * w1 + normal[2, j] * w2)
    p = d2 * np.sqrt(d2) / (area[j] * cos_y)
    return p if np.isfinite(p) else 0.0


@jit
def _sample_blocks(x, idx, one, axis1, axis2, axis3, v0, len1, len2, center, e1, e2, normal, area, rectangle,
                   emitted, omega_min, grazing, u1, u2, point, direction, distance, pdf, radiance):
    """Parallelograms.sample_li by solid angle (with finite_sample's direction and distance, and each
    receiver's light's radiance), BLOCK receivers at a time through the lanes; the area point and
    area_pdf where `use` fails."""
    B = BLOCK
    lane = np.zeros(ROWS * B)
    if one:
        for b in range(B):
            _fill_light(lane, b, 0, axis1, axis2, axis3, v0, len1, len2, center, rectangle)
    p = np.empty(3)
    n = x.shape[1]
    for start in range(0, n, B):
        size = min(B, n - start)
        _fill_block(lane, start, size, x, idx, one, axis1, axis2, axis3, v0, len1, len2, center, rectangle)
        for b in range(size):
            lane[LU1 * B + b] = u1[start + b]
        for b in range(size):
            lane[LU2 * B + b] = u2[start + b]
        _lane_frame(lane, size)
        _lane_angles(lane, size)
        _lane_spherical(lane, size, omega_min, grazing)
        for b in range(size):                            # area sampling: the point and area_pdf
            if lane[LUSE * B + b] == 0.0:
                i = start + b
                j = 0 if one else idx[i]
                for c in range(3):
                    p[c] = v0[c, j] + u1[i] * e1[c, j] + u2[i] * e2[c, j]
                    lane[(LPOINT + c) * B + b] = p[c]
                lane[LPDF * B + b] = _area_pdf(x, i, p, j, normal, area)
        _lane_directions(lane, size)
        for c in range(3):                               # the outputs, row by row
            for b in range(size):
                point[c, start + b] = lane[(LPOINT + c) * B + b]
            for b in range(size):
                direction[c, start + b] = lane[(LDIR + c) * B + b]
            if one:
                for b in range(size):
                    radiance[c, start + b] = emitted[c, 0]
            else:
                for b in range(size):
                    radiance[c, start + b] = emitted[c, idx[start + b]]
        for b in range(size):
            distance[start + b] = lane[LDIST * B + b]
        for b in range(size):
            pdf[start + b] = lane[LPDF * B + b]


@jit
def _pdf_blocks(x, idx, one, axis1, axis2, axis3, v0, len1, len2, center, normal, area, rectangle,
                omega_min, grazing, point, pdf, omega_out):
    """Parallelograms.pdf_li by solid angle (1 / Omega where `use` holds, as sample_li, else area_pdf of
    `point`) and each receiver's Omega, through the lanes of the frame and the angles."""
    B = BLOCK
    lane = np.zeros(ROWS * B)
    if one:
        for b in range(B):
            _fill_light(lane, b, 0, axis1, axis2, axis3, v0, len1, len2, center, rectangle)
    p = np.empty(3)
    n = x.shape[1]
    for start in range(0, n, B):
        size = min(B, n - start)
        _fill_block(lane, start, size, x, idx, one, axis1, axis2, axis3, v0, len1, len2, center, rectangle)
        _lane_frame(lane, size)
        _lane_omega(lane, size)
        for b in range(size):
            i = start + b
            j = 0 if one else idx[i]
            omega = lane[LOMEGA * B + b]
            omega_out[i] = omega
            if (rectangle[j] and omega >= omega_min and np.isfinite(omega)
                    and -lane[(LF + 4) * B + b] >= grazing * lane[LCD * B + b]):
                pdf[i] = 1.0 / omega
            else:
                p[0], p[1], p[2] = point[0, i], point[1, i], point[2, i]
                pdf[i] = _area_pdf(x, i, p, j, normal, area)


def _light_index(lights, idx):
    """(one, index): whether every receiver sees the same light, and the int64 light index the
    kernels read (one entry when `one`)."""
    one = np.ndim(idx) == 0 or lights.count == 1
    index = np.zeros(1, np.int64) if one else np.ascontiguousarray(idx, dtype=np.int64)
    if one and np.ndim(idx) == 0:
        index[0] = int(idx)
    return one, index


def sample_li(lights, x, idx, u1, u2, omega_min, grazing):
    """(point, direction, distance, pdf, radiance) of Parallelograms.sample_li by solid angle for
    receivers x (rows) and lights idx (an int array, or one light) of lights (a Parallelograms);
    omega_min, grazing: parallelograms.py's OMEGA_MIN and GRAZING."""
    n = x.shape[1]
    one, index = _light_index(lights, idx)
    point, direction, distance, pdf = np.empty((3, n)), np.empty((3, n)), np.empty(n), np.empty(n)
    radiance = np.empty((3, n))
    _sample_blocks(contiguous(x), index, one, lights.axis1, lights.axis2, lights.axis3, lights.v0, lights.len1,
                   lights.len2, lights.center, lights.e1, lights.e2, lights.normal, lights.area, lights.rectangle,
                   read_only(lights.radiance), omega_min, grazing, fitted(u1, (n,)), fitted(u2, (n,)),
                   point, direction, distance, pdf, radiance)
    return point, direction, distance, pdf, radiance


def _pdf_and_omega(lights, x, idx, point, omega_min, grazing):
    n = x.shape[1]
    one, index = _light_index(lights, idx)
    pdf, omega = np.empty(n), np.empty(n)
    _pdf_blocks(contiguous(x), index, one, lights.axis1, lights.axis2, lights.axis3, lights.v0, lights.len1,
                lights.len2, lights.center, lights.normal, lights.area, lights.rectangle, omega_min, grazing,
                contiguous(point), pdf, omega)
    return pdf, omega


def pdf_li(lights, x, idx, point, omega_min, grazing):
    """Parallelograms.pdf_li by solid angle."""
    return _pdf_and_omega(lights, x, idx, point, omega_min, grazing)[0]


def solid_angle(lights, x, idx):
    """Parallelograms.solid_angle: Omega of each light seen from x."""
    return _pdf_and_omega(lights, x, idx, x, 1e-6, 1e-5)[1]


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    from types import SimpleNamespace
    rows = np.eye(3)[:, :, None].repeat(2, axis=2)             # two unit squares at z = 2
    lights = SimpleNamespace(count=2, axis1=rows[0], axis2=rows[1], axis3=rows[2], len1=np.ones(2), len2=np.ones(2),
                             e1=rows[0], e2=rows[1], normal=rows[2], area=np.ones(2), rectangle=np.ones(2, np.bool_),
                             radiance=np.ones((3, 2)),
                             v0=np.array([[0.0, 1.0], [0.0, 0.0], [2.0, 2.0]]),
                             center=np.array([[0.5, 1.5], [0.5, 0.5], [2.0, 2.0]]))
    x, idx = np.zeros((3, 2)), np.array([0, 1])
    sample_li(lights, x, idx, np.full(2, 0.5), np.full(2, 0.5), 1e-6, 1e-5)
    pdf_li(lights, x, idx, np.ones((3, 2)), 1e-6, 1e-5)
