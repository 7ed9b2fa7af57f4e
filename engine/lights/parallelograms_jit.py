"""engine/lights/parallelograms.py's spherical-rectangle arithmetic compiled with numba: the local
frame and edge-plane normals of each light seen from x (`_frame` up to the arcsines) and the point
the pair (u1, u2) maps to (`_spherical_point`), one loop over the receivers each.  The arcsines
stay NumPy's (its vectorised arcsin and the C library's differ in the last bit), called between the
two loops; everything else repeats the NumPy path's float64 operations in the same order (+, -, *,
/, sqrt, and the C library's cos and sin, which NumPy also calls): the same points and densities
bit for bit (tests/lights/test_parallelograms_jit.py).  sample_li's loop after the arcsines goes
BLOCK receivers at a time (`_sample_blocks`): the cos and sin in a scalar loop that copies the
block's inputs into one flat lane array, the square roots and divisions of the spherical point and
of the directions in loops LLVM vectorises (`_lane_spherical`, `_lane_directions`: every branch a
select), the area fallback per receiver where it applies; `_frame_blocks` likewise runs `_frame`'s
arithmetic in the vectorised `_lane_frame`.  Imported only through
engine/core/backend.py's choice (it imports numba)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)
inline = nb.njit(cache=True, error_model="numpy", nogil=True, inline="always")     # inlined into its callers

BIG = np.finfo(np.float64).max          # what np.nan_to_num makes of +inf


@jit
def _clip(v, lo, hi):
    """np.clip(v, lo, hi) as NumPy's clip loop: min(max(v, lo), hi) by > and <, NaN kept."""
    if v != v:
        return v
    m = v if v > lo else lo
    if m != m:
        return m
    return m if m < hi else hi


@jit
def _frame(x, idx, one, axis1, axis2, axis3, v0, len1, len2, center, az_out, f, args, cdist):
    """Per receiver i of light j: f rows x0, y0, x1, y1, z0, e0, e2; az_out the flipped z axis; args
    the four arcsine arguments clip(-e_a e_b, -1, 1); cdist |centre - x|."""
    for i in range(x.shape[1]):
        j = 0 if one else idx[i]
        r0, r1, r2 = v0[0, j] - x[0, i], v0[1, j] - x[1, i], v0[2, j] - x[2, i]
        z0 = r0 * axis3[0, j] + r1 * axis3[1, j] + r2 * axis3[2, j]
        flip = -1.0 if z0 > 0.0 else 1.0
        az_out[0, i], az_out[1, i], az_out[2, i] = axis3[0, j] * flip, axis3[1, j] * flip, axis3[2, j] * flip
        z0 = z0 * flip
        x0 = r0 * axis1[0, j] + r1 * axis1[1, j] + r2 * axis1[2, j]
        y0 = r0 * axis2[0, j] + r1 * axis2[1, j] + r2 * axis2[2, j]
        x1, y1 = x0 + len1[j], y0 + len2[j]
        z2 = z0 * z0
        e0 = -y0 / np.sqrt(y0 * y0 + z2)
        e1 = x1 / np.sqrt(x1 * x1 + z2)
        e2 = y1 / np.sqrt(y1 * y1 + z2)
        e3 = -x0 / np.sqrt(x0 * x0 + z2)
        args[0, i] = _clip(-e0 * e1, -1.0, 1.0)
        args[1, i] = _clip(-e1 * e2, -1.0, 1.0)
        args[2, i] = _clip(-e2 * e3, -1.0, 1.0)
        args[3, i] = _clip(-e3 * e0, -1.0, 1.0)
        f[0, i], f[1, i], f[2, i], f[3, i], f[4, i], f[5, i], f[6, i] = x0, y0, x1, y1, z0, e0, e2
        c0, c1, c2 = center[0, j] - x[0, i], center[1, j] - x[1, i], center[2, j] - x[2, i]
        cdist[i] = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)


# _frame_blocks' lane rows: the receiver, its light's corner, axes, edge lengths and centre; then the
# outputs: the flipped z axis, the frame's rows (f), the arcsine arguments and |centre - x|.
FX, FV0, FA1, FA2, FA3, FLEN1, FLEN2, FC = 0, 3, 6, 9, 12, 15, 16, 17
FAZ, FF, FARGS, FCD = 20, 23, 30, 34
FROWS = 35
FRAME_BLOCK = 64


@jit
def _lane_frame(lane, size):
    """_frame's arithmetic for lanes b < size (rows at constant offsets of FRAME_BLOCK), the same
    operations in the same order, branches as selects: a loop LLVM vectorises."""
    B = FRAME_BLOCK
    for b in range(size):
        x0_, x1_, x2_ = lane[FX * B + b], lane[(FX + 1) * B + b], lane[(FX + 2) * B + b]
        r0, r1, r2 = lane[FV0 * B + b] - x0_, lane[(FV0 + 1) * B + b] - x1_, lane[(FV0 + 2) * B + b] - x2_
        a0, a1, a2 = lane[FA3 * B + b], lane[(FA3 + 1) * B + b], lane[(FA3 + 2) * B + b]
        z0 = r0 * a0 + r1 * a1 + r2 * a2
        flip = -1.0 if z0 > 0.0 else 1.0
        lane[FAZ * B + b], lane[(FAZ + 1) * B + b], lane[(FAZ + 2) * B + b] = a0 * flip, a1 * flip, a2 * flip
        z0 = z0 * flip
        x0 = r0 * lane[FA1 * B + b] + r1 * lane[(FA1 + 1) * B + b] + r2 * lane[(FA1 + 2) * B + b]
        y0 = r0 * lane[FA2 * B + b] + r1 * lane[(FA2 + 1) * B + b] + r2 * lane[(FA2 + 2) * B + b]
        x1, y1 = x0 + lane[FLEN1 * B + b], y0 + lane[FLEN2 * B + b]
        z2 = z0 * z0
        e0 = -y0 / np.sqrt(y0 * y0 + z2)
        e1 = x1 / np.sqrt(x1 * x1 + z2)
        e2 = y1 / np.sqrt(y1 * y1 + z2)
        e3 = -x0 / np.sqrt(x0 * x0 + z2)
        lane[FARGS * B + b] = _clip_select(-e0 * e1, -1.0, 1.0)
        lane[(FARGS + 1) * B + b] = _clip_select(-e1 * e2, -1.0, 1.0)
        lane[(FARGS + 2) * B + b] = _clip_select(-e2 * e3, -1.0, 1.0)
        lane[(FARGS + 3) * B + b] = _clip_select(-e3 * e0, -1.0, 1.0)
        lane[FF * B + b], lane[(FF + 1) * B + b], lane[(FF + 2) * B + b], lane[(FF + 3) * B + b] = x0, y0, x1, y1
        lane[(FF + 4) * B + b], lane[(FF + 5) * B + b], lane[(FF + 6) * B + b] = z0, e0, e2
        c0, c1, c2 = lane[FC * B + b] - x0_, lane[(FC + 1) * B + b] - x1_, lane[(FC + 2) * B + b] - x2_
        lane[FCD * B + b] = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)


@jit
def _fill_frame_light(lane, b, j, axis1, axis2, axis3, v0, len1, len2, center):
    B = FRAME_BLOCK
    for c in range(3):
        lane[(FV0 + c) * B + b], lane[(FA1 + c) * B + b] = v0[c, j], axis1[c, j]
        lane[(FA2 + c) * B + b], lane[(FA3 + c) * B + b] = axis2[c, j], axis3[c, j]
        lane[(FC + c) * B + b] = center[c, j]
    lane[FLEN1 * B + b], lane[FLEN2 * B + b] = len1[j], len2[j]


@jit
def _frame_blocks(x, idx, one, axis1, axis2, axis3, v0, len1, len2, center, az_out, f, args, cdist):
    """_frame's outputs, FRAME_BLOCK receivers at a time through the lanes of _lane_frame."""
    B = FRAME_BLOCK
    lane = np.zeros(FROWS * B)
    if one:
        for b in range(B):
            _fill_frame_light(lane, b, 0, axis1, axis2, axis3, v0, len1, len2, center)
    n = x.shape[1]
    for start in range(0, n, B):
        size = min(B, n - start)
        for b in range(size):
            i = start + b
            if not one:
                _fill_frame_light(lane, b, idx[i], axis1, axis2, axis3, v0, len1, len2, center)
            lane[FX * B + b], lane[(FX + 1) * B + b], lane[(FX + 2) * B + b] = x[0, i], x[1, i], x[2, i]
        _lane_frame(lane, size)
        for b in range(size):
            i = start + b
            for c in range(3):
                az_out[c, i] = lane[(FAZ + c) * B + b]
            for k in range(7):
                f[k, i] = lane[(FF + k) * B + b]
            for k in range(4):
                args[k, i] = lane[(FARGS + k) * B + b]
            cdist[i] = lane[FCD * B + b]


@nb.njit(cache=True, error_model="numpy", nogil=True, inline="always")
def _rectangle_point(f, i, omega, g23, u1, u2):
    """The point (u1, u2) maps to on receiver i's spherical rectangle (f's rows x0, y0, x1, y1, z0,
    e0, e2; Omega and g2 + g3 of its frame), as (xu, yv, z0) in the light's frame, for _point
    (parallelograms.py _spherical_point; _lane_spherical repeats it with selects)."""
    x0, y0, x1, y1, z0, e0, e2 = f[0, i], f[1, i], f[2, i], f[3, i], f[4, i], f[5, i], f[6, i]
    au = u1 * omega + g23
    fu = (np.cos(au) * e0 + e2) / np.sin(au)
    cu = _clip(np.copysign(1.0, fu) / np.sqrt(fu * fu + e0 * e0), -1.0, 1.0)
    s = np.sqrt(1.0 - cu * cu)
    if not (s >= 1e-300 or s != s):                      # np.maximum(s, 1e-300)
        s = 1e-300
    xu = _clip(-(cu * z0) / s, x0, x1)
    d2 = xu * xu + z0 * z0
    h0 = y0 / np.sqrt(d2 + y0 * y0)
    h1 = y1 / np.sqrt(d2 + y1 * y1)
    hv = h0 + u2 * (h1 - h0)
    if hv * hv < 1.0 - 1e-12:
        yv = hv * np.sqrt(d2) / np.sqrt(1.0 - hv * hv)
    else:
        yv = y1
    if yv != yv:                                         # np.nan_to_num
        yv = 0.0
    elif yv == np.inf:
        yv = BIG
    elif yv == -np.inf:
        yv = -BIG
    return xu, _clip(yv, y0, y1), z0


@jit
def _point(x, idx, one, axis1, axis2, az, f, omega, g23, u1, u2, out):
    for i in range(x.shape[1]):
        j = 0 if one else idx[i]
        xu, yv, z0 = _rectangle_point(f, i, omega[i], g23[i], u1[i], u2[i])
        for c in range(3):
            out[c, i] = x[c, i] + xu * axis1[c, j] + yv * axis2[c, j] + z0 * az[c, i]


BLOCK = 64                              # receivers of a block in the lanes of _sample_blocks
# Rows of the lane array (row k of receiver b at k * BLOCK + b): the receiver, its frame, Omega, cos and
# sin of its angle au, |centre - x|, (u1, u2), the flipped z axis, its light's axes and rectangle flag;
# then the outputs point, direction, distance, pdf and `use` (1.0 where the spherical point holds).
LX, LF, LOMEGA, LCOS, LSIN, LCDIST, LU1, LU2, LAZ, LAX1, LAX2, LRECT = 0, 3, 10, 11, 12, 13, 14, 15, 16, 19, 22, 25
LPOINT, LDIR, LDIST, LPDF, LUSE = 26, 29, 32, 33, 34
ROWS = 35


@inline
def _clip_select(v, lo, hi):
    """_clip as selects (the same value)."""
    m = v if v > lo else lo
    r = m if m < hi else hi
    r = m if m != m else r
    return v if v != v else r


@jit
def _lane_spherical(lane, size, omega_min, grazing):
    """sample_li's `use` predicate, spherical point (_rectangle_point after the cos and sin) and
    1 / Omega for lanes b < size, every receiver's (the area fallback is _sample_blocks'): the
    operations of parallelograms.py sample_li in the same order, every branch a select (both sides
    computed, the same numbers), so that LLVM vectorises the loop (one flat array, rows at constant
    offsets: selection_jit._lane_importances).  A select between this point and the area point
    here kept the loop scalar (LLVM moved the area point's loads into a branch)."""
    for b in range(size):
        x0, x1, x2 = lane[LX * BLOCK + b], lane[(LX + 1) * BLOCK + b], lane[(LX + 2) * BLOCK + b]
        fx0, fy0 = lane[LF * BLOCK + b], lane[(LF + 1) * BLOCK + b]
        fx1, fy1 = lane[(LF + 2) * BLOCK + b], lane[(LF + 3) * BLOCK + b]
        z0, e0, e2 = lane[(LF + 4) * BLOCK + b], lane[(LF + 5) * BLOCK + b], lane[(LF + 6) * BLOCK + b]
        omega, cd, u2 = lane[LOMEGA * BLOCK + b], lane[LCDIST * BLOCK + b], lane[LU2 * BLOCK + b]
        use = (lane[LRECT * BLOCK + b] != 0.0) & (omega >= omega_min) & (omega - omega == 0.0) & (-z0 >= grazing * cd)
        fu = (lane[LCOS * BLOCK + b] * e0 + e2) / lane[LSIN * BLOCK + b]
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
        lane[LPOINT * BLOCK + b] = (x0 + xu * lane[LAX1 * BLOCK + b] + yv * lane[LAX2 * BLOCK + b]
                                    + z0 * lane[LAZ * BLOCK + b])
        lane[(LPOINT + 1) * BLOCK + b] = (x1 + xu * lane[(LAX1 + 1) * BLOCK + b] + yv * lane[(LAX2 + 1) * BLOCK + b]
                                          + z0 * lane[(LAZ + 1) * BLOCK + b])
        lane[(LPOINT + 2) * BLOCK + b] = (x2 + xu * lane[(LAX1 + 2) * BLOCK + b] + yv * lane[(LAX2 + 2) * BLOCK + b]
                                          + z0 * lane[(LAZ + 2) * BLOCK + b])
        lane[LPDF * BLOCK + b] = 1.0 / omega
        lane[LUSE * BLOCK + b] = 1.0 if use else 0.0


@jit
def _lane_directions(lane, size):
    """finite_sample's distance and direction of each lane's point (vectorised as above)."""
    for b in range(size):
        w0 = lane[LPOINT * BLOCK + b] - lane[LX * BLOCK + b]
        w1 = lane[(LPOINT + 1) * BLOCK + b] - lane[(LX + 1) * BLOCK + b]
        w2 = lane[(LPOINT + 2) * BLOCK + b] - lane[(LX + 2) * BLOCK + b]
        dist = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        lane[LDIST * BLOCK + b] = dist
        lane[LDIR * BLOCK + b], lane[(LDIR + 1) * BLOCK + b], lane[(LDIR + 2) * BLOCK + b] = w0 / dist, w1 / dist, w2 / dist


@jit
def _fill_light(lane, b, j, axis1, axis2, rectangle):
    for c in range(3):
        lane[(LAX1 + c) * BLOCK + b], lane[(LAX2 + c) * BLOCK + b] = axis1[c, j], axis2[c, j]
    lane[LRECT * BLOCK + b] = 1.0 if rectangle[j] else 0.0


@jit
def _sample_blocks(x, idx, one, axis1, axis2, v0, e1, e2, normal, area, rectangle, omega_min, grazing, az, f, g,
                   cdist, u1, u2, point, direction, distance, pdf):
    """sample_li after the arcsines, BLOCK receivers at a time, the same numbers: their inputs copied into the lanes with
    Omega and the C library's cos and sin of au = u1 Omega + (g2 + g3) (scalar calls, as NumPy makes
    them); the spherical points in the vectorised _lane_spherical; the area point and area_pdf where
    `use` fails (rare: near a light's plane, parallelograms); the directions in _lane_directions."""
    lane = np.zeros(ROWS * BLOCK)
    if one:
        for b in range(BLOCK):
            _fill_light(lane, b, 0, axis1, axis2, rectangle)
    n = x.shape[1]
    for start in range(0, n, BLOCK):
        size = min(BLOCK, n - start)
        for b in range(size):
            i = start + b
            if not one:
                _fill_light(lane, b, idx[i], axis1, axis2, rectangle)
            omega = -(g[0, i] + g[1, i] + g[2, i] + g[3, i])
            au = u1[i] * omega + (g[2, i] + g[3, i])
            lane[LOMEGA * BLOCK + b], lane[LCOS * BLOCK + b], lane[LSIN * BLOCK + b] = omega, np.cos(au), np.sin(au)
            lane[LCDIST * BLOCK + b], lane[LU2 * BLOCK + b] = cdist[i], u2[i]
            for c in range(3):
                lane[(LX + c) * BLOCK + b], lane[(LAZ + c) * BLOCK + b] = x[c, i], az[c, i]
            for k in range(7):
                lane[(LF + k) * BLOCK + b] = f[k, i]
        _lane_spherical(lane, size, omega_min, grazing)
        for b in range(size):                            # area sampling: the point and area_pdf
            if lane[LUSE * BLOCK + b] == 0.0:
                i = start + b
                j = 0 if one else idx[i]
                for c in range(3):
                    lane[(LPOINT + c) * BLOCK + b] = v0[c, j] + u1[i] * e1[c, j] + u2[i] * e2[c, j]
                w0, w1, w2 = (lane[LPOINT * BLOCK + b] - x[0, i], lane[(LPOINT + 1) * BLOCK + b] - x[1, i],
                              lane[(LPOINT + 2) * BLOCK + b] - x[2, i])
                d2 = w0 * w0 + w1 * w1 + w2 * w2
                cos_y = np.abs(normal[0, j] * w0 + normal[1, j] * w1 + normal[2, j] * w2)
                p = d2 * np.sqrt(d2) / (area[j] * cos_y)
                lane[LPDF * BLOCK + b] = p if np.isfinite(p) else 0.0
        _lane_directions(lane, size)
        for b in range(size):
            i = start + b
            for c in range(3):
                point[c, i], direction[c, i] = lane[(LPOINT + c) * BLOCK + b], lane[(LDIR + c) * BLOCK + b]
            distance[i], pdf[i] = lane[LDIST * BLOCK + b], lane[LPDF * BLOCK + b]


@jit
def _pdf(x, idx, one, normal, area, rectangle, omega_min, grazing, f, g, cdist, point, pdf):
    """pdf_li after the arcsines, one receiver at a time: 1 / Omega where `use` holds (as sample_li),
    else area_pdf of `point`."""
    for i in range(x.shape[1]):
        j = 0 if one else idx[i]
        omega = -(g[0, i] + g[1, i] + g[2, i] + g[3, i])
        if rectangle[j] and omega >= omega_min and np.isfinite(omega) and -f[4, i] >= grazing * cdist[i]:
            pdf[i] = 1.0 / omega
        else:
            w0, w1, w2 = point[0, i] - x[0, i], point[1, i] - x[1, i], point[2, i] - x[2, i]
            d2 = w0 * w0 + w1 * w1 + w2 * w2
            cos_y = np.abs(normal[0, j] * w0 + normal[1, j] * w1 + normal[2, j] * w2)
            p = d2 * np.sqrt(d2) / (area[j] * cos_y)
            pdf[i] = p if np.isfinite(p) else 0.0


def _c(a):
    return np.ascontiguousarray(a, dtype=np.float64)


def _per_receiver(a, n):
    """a (an array of n, or one number for all) as n contiguous float64 (np.broadcast_to only when
    needed: its Python costs more than the kernels' loops on small batches)."""
    if isinstance(a, np.ndarray) and a.shape == (n,):
        return _c(a)
    return _c(np.broadcast_to(a, (n,)))


def _light_index(lights, idx):
    """(one, index): whether every receiver sees the same light, and the int64 light index the
    kernels read (one entry when `one`)."""
    one = np.ndim(idx) == 0 or lights.count == 1
    index = np.zeros(1, np.int64) if one else np.ascontiguousarray(idx, dtype=np.int64)
    if one and np.ndim(idx) == 0:
        index[0] = int(idx)
    return one, index


def _frame_of(lights, x, one, index):
    """_frame's outputs (az, f, args, cdist) for contiguous receivers x."""
    n = x.shape[1]
    az, f, args, cdist = np.empty((3, n)), np.empty((7, n)), np.empty((4, n)), np.empty(n)
    _frame_blocks(x, index, one, lights.axis1, lights.axis2, lights.axis3, lights.v0, lights.len1, lights.len2, lights.center,
           az, f, args, cdist)
    return az, f, args, cdist


def frame_terms(lights, x, idx):
    """(az (3, N), f (7, N): x0 y0 x1 y1 z0 e0 e2, args (4, N), cdist (N,)) of lights (a
    Parallelograms) seen from x (rows) for the lights idx (an int array, or one light)."""
    one, index = _light_index(lights, idx)
    return _frame_of(lights, _c(x), one, index)


def spherical_point(lights, x, idx, az, f, omega, g23, u1, u2):
    """The point of each rectangle that (u1, u2) maps to (parallelograms.py _spherical_point)."""
    n = x.shape[1]
    one, index = _light_index(lights, idx)
    out = np.empty((3, n))
    _point(_c(x), index, one, lights.axis1, lights.axis2, az, f, _c(omega), _c(g23),
           _per_receiver(u1, n), _per_receiver(u2, n), out)
    return out


def sample_li(lights, x, idx, u1, u2, omega_min, grazing):
    """(point, direction, distance, pdf) of Parallelograms.sample_li by solid angle: the frame's loop,
    NumPy's arcsines of the four arguments, then the rest (_sample_blocks); omega_min, grazing:
    parallelograms.py's OMEGA_MIN and GRAZING."""
    n = x.shape[1]
    x = _c(x)
    one, index = _light_index(lights, idx)
    az, f, args, cdist = _frame_of(lights, x, one, index)
    g = np.arcsin(args)
    point, direction, distance, pdf = np.empty((3, n)), np.empty((3, n)), np.empty(n), np.empty(n)
    _sample_blocks(x, index, one, lights.axis1, lights.axis2, lights.v0, lights.e1, lights.e2, lights.normal, lights.area,
            lights.rectangle, omega_min, grazing, az, f, g, cdist, _per_receiver(u1, n),
            _per_receiver(u2, n), point, direction, distance, pdf)
    return point, direction, distance, pdf


def pdf_li(lights, x, idx, point, omega_min, grazing):
    """Parallelograms.pdf_li by solid angle: the frame's loop, NumPy's arcsines, then _pdf."""
    n = x.shape[1]
    x = _c(x)
    one, index = _light_index(lights, idx)
    az, f, args, cdist = _frame_of(lights, x, one, index)
    pdf = np.empty(n)
    _pdf(x, index, one, lights.normal, lights.area, lights.rectangle, omega_min, grazing, f, np.arcsin(args), cdist,
         _c(point), pdf)
    return pdf


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    from types import SimpleNamespace
    rows = np.eye(3)[:, :, None].repeat(2, axis=2)             # two unit squares at z = 2
    lights = SimpleNamespace(count=2, axis1=rows[0], axis2=rows[1], axis3=rows[2], len1=np.ones(2), len2=np.ones(2),
                             e1=rows[0], e2=rows[1], normal=rows[2], area=np.ones(2), rectangle=np.ones(2, np.bool_),
                             v0=np.array([[0.0, 1.0], [0.0, 0.0], [2.0, 2.0]]),
                             center=np.array([[0.5, 1.5], [0.5, 0.5], [2.0, 2.0]]))
    x, idx = np.zeros((3, 2)), np.array([0, 1])
    az, f, args, cdist = frame_terms(lights, x, idx)
    sample_li(lights, x, idx, np.full(2, 0.5), np.full(2, 0.5), 1e-6, 1e-5)
    pdf_li(lights, x, idx, np.ones((3, 2)), 1e-6, 1e-5)
    spherical_point(lights, x, idx, az, f, np.ones(2), np.zeros(2), np.full(2, 0.5), np.full(2, 0.5))
