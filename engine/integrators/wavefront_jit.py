"""engine/integrators/path_tracer.py's glue compiled with numba:

* the end of the scatter stage (the paths' delta flag and ray kind, the side they leave on, beta x
  value), the Russian roulette (which paths go on and their throughput after the survival division; or
  the deferred roulette in Cycles' order: which paths trace their next ray and the factor their
  throughput takes after its emission) and the compaction of the surviving paths (their next ray
  origins, the hit point moved off the surface to the side they leave on, directions and throughputs)
  in one pass (`survivors`: no throughput rows and keep flags between them) instead of some thirty
  NumPy passes (path_tracer.py scatter's tail, roulette or deferred_roulette, next_rays);
* the direct light of a Lambertian BSDF with one shadow ray per hit, flat shading and no Normal
  input (`PathTracer.direct_light`'s commonest case), around its light sample and its shadow rays:
  the tests that keep a sample (`light_tests`) and its weight, MIS and Le f cos / p_l
  (`lambert_light`), one loop each instead of some twenty NumPy passes;
* the emission a ray reaches (`PathTracer.emission` and `emission_weight` without caustic photons):
  the emitters' light numbers (`emitter_lights`) and the MIS-weighted sum into the radiance
  (`add_emission`), two loops instead of some thirty NumPy calls on a few rays; the background the rays
  that leave the scene see (`PathTracer.misses` on an opaque film, `background_light`) in the same loop,
  around the world's pdf;
* Light Paths' clamp (engine/integrators/light_paths.py clamp_contribution) inside those sums and the
  Lambertian direct light's (`_clamp_scale`), the bounce counts per type (`count_bounces`) and the rays
  whose next hit only emits (`final_groups`: the depth limit, a type past its limit, the deferred
  roulette), one loop each instead of some five NumPy passes each;
* the facing and shading normals of smooth-shaded hits (`facing`: path_tracer.facing_normals);
* the gathers of the path state (`take`: `Paths.take`'s fields, twice a bounce): a plain loop per row,
  which costs 0.55-0.75x NumPy 1.26's `take` (its per-element index checks) on the same indices.

The float64 operations are those of the NumPy path in the same order, so the same bits
(tests/integrators/test_wavefront_jit.py).  Imported only through engine/core/backend.py's choice
(it imports numba)."""
from __future__ import annotations

import numpy as np

from ..core.backend import numba_module
from ..core.kernel_inputs import fitted, read_only
from ..materials.protocol import DELTA_LOBE, DIFFUSE_LOBE, REFLECTION_LOBE, STRAIGHT_LOBE, TRANSMISSION_LOBE
from ..geometry.shapes.light_polygons import RAY_KINDS
from .light_paths import CLAMP_SCALE, DIFFUSE_BOUNCE, GLOSSY_BOUNCE, TRANSMISSION_BOUNCE, TRANSPARENT_BOUNCE

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

NO_ROWS = np.zeros((3, 0))
# path_tracer.py's ray kinds (not imported from it: it imports this module), LightPolygons' order
CAMERA_RAY, DIFFUSE_RAY, GLOSSY_RAY, TRANSMISSION_RAY = (RAY_KINDS.index(k) for k in
                                                         ("camera", "diffuse", "glossy", "transmission"))


@jit
def _light_tests(n, w, normal, step, pdf, distance, one_sided, any_one_sided, cos_x, cos_ly):
    """cos_x = <n, w>, cos_ly = <light normal, w> and the samples kept (direct_light's `ok`:
    light on the viewer's side, not edge-on, a density, a distance, a one-sided light's front).
    Sample i's light normal is column i x step (step 0: one normal for all)."""
    k = pdf.shape[0]
    valid = np.empty(k, np.int64)
    count = 0
    for i in range(k):
        c = n[0, i] * w[0, i] + n[1, i] * w[1, i] + n[2, i] * w[2, i]
        q = i * step
        cl = normal[0, q] * w[0, i] + normal[1, q] * w[1, i] + normal[2, q] * w[2, i]
        cos_x[i], cos_ly[i] = c, cl
        ok = c > 0.0 and cl != 0.0 and pdf[i] > 0.0 and distance[i] > 0.0
        if any_one_sided and one_sided[i] and cl >= 0.0:
            ok = False
        if ok:
            valid[count] = i
            count += 1
    return valid[:count]


@jit
def _clamp_scale(c0, c1, c2, bounce, clamp):
    """light_paths.clamp_contribution's factor of one contribution (c0, c1, c2) reached after `bounce`
    bounces: bound / (|R| + |G| + |B|) where the sum exceeds bound = CLAMP_SCALE x the limit, else 1.
    clamp: (direct_max, limit_direct, limit_indirect): Clamp Direct up to bounce direct_max."""
    direct_max, limit_direct, limit_indirect = clamp
    total = (abs(c0) + abs(c1)) + abs(c2)             # np.abs(rows).sum(axis=0): row after row
    bound = CLAMP_SCALE * (limit_direct if bounce <= direct_max else limit_indirect)
    return bound / total if total > bound else 1.0


NO_CLAMP = (0, np.inf, np.inf)                        # (the kernels' clamp argument when clamping is off)


def clamp_args(clamp, direct_max):
    """(clamping, the kernels' clamp tuple) of a PathTracer's clamp limits (None: off) for the light
    reached after up to direct_max bounces counting as direct."""
    if clamp is None:
        return False, NO_CLAMP
    return True, (int(direct_max), float(clamp[0]), float(clamp[1]))


@jit
def _lambert_light(valid, blocked, cos_x, pdf, p_b, cosine_pdf, light, reachable, mis, radiance, albedo, out,
                   add, beta, start, clamping, bounce, clamp):
    """out = Le weight rho / pi: weight = cos / p_l (times the power heuristic's light weight
    against p_b under MIS, with p_b 0 for lights a BSDF sample cannot reach) where unblocked,
    0 elsewhere; the products in direct_light's order ((Le weight) rho) (1 / pi).  With `add`,
    out[:, start + i] += beta[:, start + i] x that instead (PathTracer.bounce's sum), scaled by
    _clamp_scale first with `clamping` (bounce: the paths' bounces, read at start + i).  cosine_pdf:
    p_b is the Lambertian's max(cos, 0) (1 / pi) (engine/materials/lambert.py pdf), computed here
    from cos_x (the same products and sum: <n, w> = <w, n>; cos > 0 for every kept sample)."""
    k = pdf.shape[0]
    weight = np.zeros(k)
    for j in range(valid.shape[0]):
        i = valid[j]
        sample = cos_x[i] / pdf[i]
        if mis:                                  # path_tracer.power_heuristic(1, p_l, 1, p_bsdf)
            p_bsdf = cos_x[i] * (1.0 / np.pi) if cosine_pdf else p_b[i]
            p_g = p_bsdf if reachable[light[i]] else 0.0
            p_f = pdf[i]
            r = (1.0 * p_g) / (1.0 * p_f)
            h = 1.0 / (1.0 + r * r)
            if not p_f > 0.0:
                h = 0.0
            elif h != h:                         # np.nan_to_num (h is never infinite)
                h = 0.0
            sample *= h
        weight[i] = 0.0 if blocked[j] else sample
    inv_pi = 1.0 / np.pi
    if add:
        for i in range(k):
            q = start + i
            c0 = beta[0, q] * (radiance[0, i] * weight[i] * albedo[0, i] * inv_pi)
            c1 = beta[1, q] * (radiance[1, i] * weight[i] * albedo[1, i] * inv_pi)
            c2 = beta[2, q] * (radiance[2, i] * weight[i] * albedo[2, i] * inv_pi)
            if clamping:
                scale = _clamp_scale(c0, c1, c2, bounce[q], clamp)
                c0, c1, c2 = c0 * scale, c1 * scale, c2 * scale
            out[0, q] += c0
            out[1, q] += c1
            out[2, q] += c2
        return
    for i in range(k):
        for c in range(3):
            out[c, i] = radiance[c, i] * weight[i] * albedo[c, i] * inv_pi


def _rows(a, k):
    return fitted(a, (3, k))


def _columns(a, k):
    """(rows, step) of rows a (3, k): column i is rows[:, i x step]; step 0 for one column broadcast
    to all (np.broadcast_to, e.g. one light's normal), which is then not copied k times."""
    if isinstance(a, np.ndarray) and a.shape == (3, k) and k > 0 and a.strides[1] == 0:
        return _rows(a[:, :1], 1), 0
    return _rows(a, k), 1


def light_tests(n, ls, any_one_sided):
    """(cos_x, cos_ly, valid) of light samples ls (engine/lights/light_set.py LightSample) at receivers
    with facing normals n (rows): direct_light's two cosines and the indices of its kept samples."""
    k = ls.pdf.shape[0]
    cos_x, cos_ly = np.empty(k), np.empty(k)
    valid = _light_tests(_rows(n, k), _rows(ls.direction, k), *_columns(ls.normal, k),
                         fitted(ls.pdf, (k,)), fitted(ls.distance, (k,)),
                         fitted(ls.one_sided, (k,), np.bool_), bool(any_one_sided),
                         cos_x, cos_ly)
    return cos_x, cos_ly, valid


def lambert_light(valid, blocked, cos_x, ls, p_b, reachable, mis, albedo, into=None):
    """(3, k) Le weight rho / pi of the samples ls (direct_light's Lambertian return, one shadow ray):
    valid from light_tests, blocked (len(valid),) from the shadow rays, p_b the BSDF's pdf of each
    sample's direction (read only under mis; None: the Lambertian's, from cos_x), reachable per
    light (LightSet.bsdf_reachable).  into: (radiance, beta, start, bounce, clamp), C-contiguous rows of
    the path state: radiance[:, start:start + k] += beta[:, start:start + k] x that, in place (returns
    None), clamped as light_paths.clamp_contribution by PathTracer.clamp_limits `clamp` (None: not) as
    direct light where bounce (the paths' bounces) is 0."""
    k = cos_x.shape[0]
    if into is None:
        out, beta, start, bounce, clamp = np.empty((3, k)), read_only(NO_ROWS), 0, read_only(NO_BOUNCES), None
    else:
        out, beta, start, bounce, clamp = into
        beta, bounce = read_only(beta), read_only(np.ascontiguousarray(bounce, np.int32))
    clamping, limits = clamp_args(clamp, 0)
    _lambert_light(np.ascontiguousarray(valid, np.int64), np.ascontiguousarray(blocked, np.bool_), cos_x,
                   fitted(ls.pdf, (k,)),
                   fitted(0.0 if p_b is None else p_b, (k,)), p_b is None,
                   np.ascontiguousarray(ls.light, np.int64), np.ascontiguousarray(reachable, np.bool_), bool(mis),
                   _rows(ls.radiance, k), _rows(albedo, k), out, into is not None, beta, int(start), clamping, bounce,
                   limits)
    return out if into is None else None


NO_BOUNCES = np.zeros(0, np.int32)


@jit
def _tail_at(i, flags, prev_delta, ray_kind, beta, value, smooth, new_d, ng, write):
    """PathTracer.scatter's tail for path i: (side, the three beta x value); with `write`, its delta flag and
    ray kind written too."""
    f = flags[i]
    transmitted = (f & TRANSMISSION_LOBE) != 0
    if write:
        prev_delta[i] = (f & DELTA_LOBE) != 0
        kind = TRANSMISSION_RAY if transmitted else (DIFFUSE_RAY if (f & DIFFUSE_LOBE) != 0 else GLOSSY_RAY)
        if (f & STRAIGHT_LOBE) != 0 and ray_kind[i] == CAMERA_RAY:
            kind = CAMERA_RAY
        ray_kind[i] = kind
    s = -1.0 if transmitted else 1.0
    wrong = smooth and (new_d[0, i] * ng[0, i] + new_d[1, i] * ng[1, i] + new_d[2, i] * ng[2, i]) * s <= 0.0
    if wrong:
        return s, 0.0, 0.0, 0.0
    return s, beta[0, i] * value[0, i], beta[1, i] * value[1, i], beta[2, i] * value[2, i]


@jit
def _max(a, b):
    """np.maximum of two scalars (NaN wins)."""
    return a if (a >= b or a != a) else b


@jit
def _survives(b0, b1, b2, bounce, delta, u, max_depth, final_rays, russian_roulette, rr_start_depth):
    """(kept, divisor) of one path in PathTracer.roulette: within the depth (a final non-delta ray at
    max_depth too), a positive throughput, and Russian roulette's survival by its largest channel."""
    within = bounce < max_depth
    if final_rays:
        within = within or (bounce == max_depth and not delta)
    m = _max(_max(b0, b1), b2)
    k = m > 0.0 and within
    divisor = 1.0
    if russian_roulette:
        survive = (m if (m <= 1.0 or m != m) else 1.0) if bounce + 1 >= rr_start_depth else 1.0   # np.minimum
        k = k and u < survive
        divisor = survive if k else 1.0
    return k, divisor


@jit
def _continuation(b0, b1, b2, bounce, u, rr_start_depth):
    """PathTracer.deferred_roulette's factor of one path's throughput after its ray's emission: 1 / the
    survival probability min(1, sqrt(max throughput)) (1 before the bounce rr_start_depth) where u is below
    it, else 0 (the path ends at its next hit)."""
    m = _max(_max(b0, b1), b2)
    survive = 1.0
    if bounce + 1 >= rr_start_depth:
        root = np.sqrt(m)
        survive = root if (root <= 1.0 or root != root) else 1.0     # np.minimum (NaN wins)
    return 1.0 / survive if u < survive else 0.0


@jit
def _survivors(beta, bounce, delta, u, max_depth, final_rays, russian_roulette, rr_start_depth, point, side, offset,
               facing, new_d, has_tail, flags, ray_kind, value, smooth, ng, deferred, rr_after):
    """PathTracer.roulette and path_tracer.next_rays in one: which paths go on (their indices, and those of
    the others in order) and the kept paths' next origin, direction and throughput after the survival
    division.
    has_tail: the scatter's tail first (_tail_at; beta: the rows before the scatter; delta and ray_kind
    written), their side and throughput computed again where the compaction needs them, not stored.
    deferred: the deferred roulette instead of the roulette (russian_roulette then False: no division),
    its factor written to rr_after[i] (_continuation)."""
    n = bounce.shape[0]
    divisor = np.empty(n)
    kept = np.empty(n, np.bool_)
    count = 0
    for i in range(n):
        if has_tail:
            _, b0, b1, b2 = _tail_at(i, flags, delta, ray_kind, beta, value, smooth, new_d, ng, True)
        else:
            b0, b1, b2 = beta[0, i], beta[1, i], beta[2, i]
        k, dv = _survives(b0, b1, b2, bounce[i], delta[i], u[i], max_depth, final_rays, russian_roulette,
                          rr_start_depth)                # PathTracer.roulette's tests, the same operations
        if deferred:
            rr_after[i] = _continuation(b0, b1, b2, bounce[i], u[i], rr_start_depth)
        kept[i] = k
        divisor[i] = dv
        if k:
            count += 1
    keep = np.empty(count, np.int64)
    ended = np.empty(n - count, np.int64)
    o = np.empty((3, count))
    d = np.empty((3, count))
    b = np.empty((3, count))
    j = 0
    e = 0
    for i in range(n):
        if not kept[i]:
            ended[e] = i
            e += 1
            continue
        keep[j] = i
        if has_tail:
            si, b0, b1, b2 = _tail_at(i, flags, delta, ray_kind, beta, value, smooth, new_d, ng, False)
        else:
            si, b0, b1, b2 = side[i], beta[0, i], beta[1, i], beta[2, i]
        s = si * offset[i]                       # path_tracer.next_rays' operations
        for c in range(3):
            o[c, j] = point[c, i] + s * facing[c, i]
            d[c, j] = new_d[c, i]
        if russian_roulette:
            b[0, j], b[1, j], b[2, j] = b0 / divisor[i], b1 / divisor[i], b2 / divisor[i]
        else:
            b[0, j], b[1, j], b[2, j] = b0, b1, b2
        j += 1
    return keep, ended, o, d, b


NO_FLAGS = np.zeros(0, np.int8)
NO_KINDS = np.zeros(0, np.int8)
NO_AFTER = np.zeros(0)                                  # (survivors' rr_after without the deferred roulette)


def survivors(beta, bounce, delta, u, max_depth, final_rays, russian_roulette, rr_start_depth, point, side, offset,
              facing, new_d, tail=None, rr_after=None):
    """(keep, ended, o, d, beta): PathTracer.roulette's paths that go on (indices, `keep`) and those that
    end (`ended`), then path_tracer.next_rays(keep, point, side, offset, facing, new_d, the roulette's
    beta) in one pass: the same arrays as roulette, np.flatnonzero and next_rays.  tail: (flags,
    ray_kind, value, ng): PathTracer.scatter's tail first, in the same pass (ng: the geometric normals
    under smooth shading, else None; beta: the paths' rows before it, of which the first len(bounce)
    are read; side unused; delta and ray_kind are written).
    rr_after: PathTracer.deferred_roulette instead of roulette (float64, C-contiguous, len(bounce)): its
    `after` written into rr_after in place, keep as its keep, the throughputs not divided."""
    f64 = np.float64
    n = bounce.shape[0]
    has_tail = tail is not None
    deferred = rr_after is not None
    if deferred and not (rr_after.dtype == f64 and rr_after.flags.c_contiguous and rr_after.shape == (n,)):
        raise ValueError("survivors: rr_after must be C-contiguous float64 of the paths' length")
    flags, ray_kind, value, ng = tail if has_tail else (NO_FLAGS, NO_KINDS, NO_ROWS, None)
    smooth = ng is not None
    return _survivors(read_only(np.ascontiguousarray(beta, f64)), read_only(np.ascontiguousarray(bounce, np.int32)),
                      delta if has_tail else np.ascontiguousarray(delta, np.bool_),
                      read_only(np.ascontiguousarray(u, f64)),
                      int(max_depth), bool(final_rays), bool(russian_roulette) and not deferred, int(rr_start_depth),
                      read_only(np.ascontiguousarray(point, f64)),
                      read_only(np.ascontiguousarray(side if not has_tail else np.zeros(0), f64)),
                      read_only(np.ascontiguousarray(offset, f64)), read_only(np.ascontiguousarray(facing, f64)),
                      read_only(np.ascontiguousarray(new_d, f64)), has_tail,
                      read_only(np.ascontiguousarray(flags, np.int8)), ray_kind,
                      read_only(np.ascontiguousarray(value, f64)), smooth,
                      read_only(np.ascontiguousarray(ng, f64) if smooth else NO_ROWS), deferred,
                      rr_after if deferred else NO_AFTER)


@jit
def _emitter_lights(idx, prev_delta, kind, prim, light_table, kind_base):
    """(places j of idx whose path's last bounce was not a delta and whose primitive is a light the
    sampler has, their lights): emission_weight's sel, light, known."""
    m = idx.shape[0]
    places = np.empty(m, np.int64)
    lights = np.empty(m, np.int64)
    count = 0
    for j in range(m):
        i = idx[j]
        if prev_delta[i]:
            continue
        k = kind[i]
        light = light_table[kind_base[k] + prim[i]] if kind_base[k] >= 0 else -1
        if light >= 0:
            places[count], lights[count] = j, light
            count += 1
    return places[:count], lights[:count]


def emitter_lights(idx, prev_delta, kind, prim, light_table, kind_base):
    """emission_weight's non-delta hits idx on emitters the light sampler has: (their places in idx,
    their lights); the light of (kind, prim) is light_table[kind_base[kind] + prim] (kind_base -1: none)."""
    return _emitter_lights(np.ascontiguousarray(idx, np.int64), prev_delta, np.ascontiguousarray(kind, np.int8),
                           np.ascontiguousarray(prim, np.int64), light_table, kind_base)


@jit
def _weights(idx, prev_delta, bsdf_pdf, places, p_light, mode, n_light):
    """(len(idx),) the weights of the light the paths idx reach: mode 0 one, 1 the path's delta flag (0 or
    1), 2 one after a delta bounce, else the power heuristic's of the BSDF sample against n_light light
    samples with p_light at `places` (0 elsewhere)."""
    m = idx.shape[0]
    w = np.ones(m)
    if mode == 1:
        for j in range(m):
            w[j] = 1.0 if prev_delta[idx[j]] else 0.0
    elif mode == 2:
        p_l = np.zeros(m)
        for q in range(places.shape[0]):
            p_l[places[q]] = p_light[q]
        for j in range(m):
            i = idx[j]
            if prev_delta[i]:
                continue
            p_f = bsdf_pdf[i]                   # path_tracer.power_heuristic(1, p_f, n_light, p_l)
            r = (n_light * p_l[j]) / (1.0 * p_f)
            h = 1.0 / (1.0 + r * r)
            if not p_f > 0.0:
                h = 0.0
            elif h != h:                         # np.nan_to_num (h is never infinite)
                h = 0.0
            w[j] = h
    return w


@jit
def _add_light(radiance, beta, idx, le, step, w, gathered, out, clamping, bounce, clamp):
    """(beta[:, idx] le) w, clamped by _clamp_scale with `clamping`, added to radiance[:, idx] in place, or
    with `gathered` to radiance[:, idx] into out (3, len(idx)) (radiance unchanged).  Path j's le is
    column j x step (step 0: one column for all)."""
    for j in range(idx.shape[0]):
        i = idx[j]
        q = j * step
        c0 = beta[0, i] * le[0, q] * w[j]
        c1 = beta[1, i] * le[1, q] * w[j]
        c2 = beta[2, i] * le[2, q] * w[j]
        if clamping:
            scale = _clamp_scale(c0, c1, c2, bounce[i], clamp)
            c0, c1, c2 = c0 * scale, c1 * scale, c2 * scale
        if gathered:
            out[0, j], out[1, j], out[2, j] = radiance[0, i] + c0, radiance[1, i] + c1, radiance[2, i] + c2
        else:
            radiance[0, i] += c0
            radiance[1, i] += c1
            radiance[2, i] += c2


@jit
def _reached_light(radiance, beta, idx, le, step, prev_delta, bsdf_pdf, places, p_light, mode, n_light, gathered, out,
                   clamping, bounce, clamp):
    """The light le the paths idx reach (an emitter hit or the sky), weighted by _weights (mode: none,
    delta only, after delta, or MIS against the light samples) and added by _add_light (clamped, in place or
    gathered into out): one loop's worth of PathTracer's emission and miss terms (`_reached` calls it)."""
    _add_light(radiance, beta, idx, le, step, _weights(idx, prev_delta, bsdf_pdf, places, p_light, mode, n_light),
               gathered, out, clamping, bounce, clamp)


def _reached(radiance, beta, idx, le, prev_delta, bsdf_pdf, places, p_light, mode, n_light, bounce, clamp, out):
    """_reached_light's call: the light le (3, len(idx)) or (3, 1) reached by the paths idx."""
    idx = np.ascontiguousarray(idx, np.int64)
    m = len(idx)
    le, step = (_rows(le, 1), 0) if le.shape[1] == 1 and m != 1 else _columns(le, m)
    clamping, limits = clamp_args(clamp, 1)
    _reached_light(radiance, read_only(np.ascontiguousarray(beta, np.float64)), idx, le, step, prev_delta,
                   NO_PDF if bsdf_pdf is None else bsdf_pdf, np.ascontiguousarray(places, np.int64),
                   np.ascontiguousarray(p_light, np.float64), int(mode), float(n_light), out is not None,
                   NO_OUT if out is None else out, clamping,
                   read_only(NO_BOUNCES if bounce is None else np.ascontiguousarray(bounce, np.int32)), limits)


def add_emission(radiance, beta, idx, le, prev_delta, bsdf_pdf, places, p_light, mode, n_light, bounce=None,
                 clamp=None):
    """PathTracer.emission's sum of the emission le (3, len(idx)) the paths idx reach, into the rows
    radiance in place, weighted as emission_weight (mode: 0 weight 1, 1 the delta flag, 2 MIS with the
    lights' pdfs p_light at `places` from emitter_lights); bsdf_pdf read only in mode 2.  clamp:
    PathTracer.clamp_limits (None: no clamping), Clamp Direct up to one bounce (bounce: the paths')."""
    _reached(radiance, beta, idx, le, prev_delta, bsdf_pdf, places, p_light, mode, n_light, bounce, clamp, None)


def background_light(radiance, beta, idx, le, prev_delta, bsdf_pdf, places, p_light, mode, n_light, bounce=None,
                     clamp=None):
    """PathTracer.misses' radiance (3, len(idx)) of the paths idx that leave the scene: theirs plus the
    background le they see ((3, len(idx)), or (3, 1) for all) weighted and clamped as add_emission's
    (mode 1 and 2: the world is a light; p_light: its pdfs at the non-delta misses `places`)."""
    out = np.empty((3, len(idx)))
    _reached(radiance, beta, idx, le, prev_delta, bsdf_pdf, places, p_light, mode, n_light, bounce, clamp, out)
    return out


@jit
def _sampled(idx, prev_delta):
    """The places j of idx whose path's last bounce was not a delta."""
    places = np.empty(idx.shape[0], np.int64)
    count = 0
    for j in range(idx.shape[0]):
        if not prev_delta[idx[j]]:
            places[count] = j
            count += 1
    return places[:count]


def sampled(idx, prev_delta):
    """np.flatnonzero(~prev_delta[idx]): the paths idx sampled at a non-delta vertex, by place in idx."""
    return _sampled(np.ascontiguousarray(idx, np.int64), prev_delta)


NO_OUT = np.zeros((3, 0))
NO_PDF = np.zeros(0)


@jit
def _facing(d, normal, shading, facing, shade):
    for i in range(facing.shape[1]):
        towards = 1.0 if d[0, i] * normal[0, i] + d[1, i] * normal[1, i] + d[2, i] * normal[2, i] < 0.0 else -1.0
        for c in range(3):
            facing[c, i] = normal[c, i] * towards
            shade[c, i] = shading[c, i] * towards


def facing(d, normal, shading):
    """path_tracer.facing_normals(d, normal, shading): the geometric normals (3, N) and the shading normals
    turned towards the rays d, both by the side of the ray the geometric one is on."""
    n = normal.shape[1]
    towards_rays, shade = np.empty((3, n)), np.empty((3, n))
    _facing(read_only(np.ascontiguousarray(d, np.float64)), read_only(np.ascontiguousarray(normal, np.float64)),
            read_only(np.ascontiguousarray(shading, np.float64)), towards_rays, shade)
    return towards_rays, shade


@jit
def _count_bounces(counts, flags):
    for i in range(flags.shape[0]):
        f = flags[i]
        if (f & STRAIGHT_LOBE) != 0:             # light_paths.bounce_type's rows
            kind = TRANSPARENT_BOUNCE
        elif (f & TRANSMISSION_LOBE) != 0:
            kind = TRANSMISSION_BOUNCE
        elif (f & DIFFUSE_LOBE) != 0:
            kind = DIFFUSE_BOUNCE
        else:
            kind = GLOSSY_BOUNCE
        counts[kind, i] += 1


def count_bounces(counts, flags):
    """LightPaths.count: each of the first len(flags) paths' scatter added to its type's row of counts
    (4, N) in place (C-contiguous int32 rows, as Paths keeps them)."""
    _count_bounces(counts, read_only(np.ascontiguousarray(flags, np.int8)))


@jit
def _final_groups(bounce, max_depth, final_rays, counts, limits, rr_after, forced, absorb):
    any_final = False
    for i in range(bounce.shape[0]):
        final = final_rays and bounce[i] > max_depth
        for t in range(counts.shape[0]):
            final = final or counts[t, i] > limits[t]
        if rr_after.shape[0] and rr_after[i] == 0.0:
            final = True
        forced[i] = absorb if final else -1
        any_final = any_final or final
    return any_final


def final_groups(bounce, max_depth, final_rays, counts, limits, rr_after, absorb):
    """PathTracer.bounce's forced groups of the rays' hits: `absorb` where the hit only emits (beyond the
    depth limit with final rays, a bounce type past its limit (counts (4, N) against limits, or None), the
    deferred roulette ended it (rr_after 0, or None)), -1 elsewhere; None where no hit only emits."""
    forced = np.empty(bounce.shape[0], np.int64)
    found = _final_groups(read_only(np.ascontiguousarray(bounce, np.int32)), int(max_depth), bool(final_rays),
                          read_only(NO_COUNTS if counts is None else np.ascontiguousarray(counts, np.int32)),
                          read_only(np.ascontiguousarray(NO_LIMITS if limits is None else limits, np.int64)),
                          read_only(NO_PDF if rr_after is None else np.ascontiguousarray(rr_after, np.float64)),
                          forced, int(absorb))
    return forced if found else None


NO_COUNTS = np.zeros((0, 0), np.int32)
NO_LIMITS = np.zeros(0, np.int64)


@jit
def _take_rows(a, index, out):
    for c in range(a.shape[0]):
        for j in range(index.shape[0]):
            out[c, j] = a[c, index[j]]


@jit
def _take_1d(a, index, out):
    for j in range(index.shape[0]):
        out[j] = a[index[j]]


# The path state's 1-D dtypes (Paths: pixel and sample int64, bounce int32, ray_kind int8, flags bool, pdfs)
TAKE_DTYPES = tuple(np.dtype(t) for t in (np.float64, np.int64, np.int32, np.int8, np.bool_))
TAKE_ROW_DTYPES = (np.dtype(np.float64), np.dtype(np.int32))     # its rows: vectors, the bounce counts


def take(arrays, index, room=0):
    """[a.take(index, axis=axis) for a, axis in arrays] of path-state arrays, each with `room`
    uninitialised entries more along its axis (path_tracer.Paths.take's room), compiled for C-contiguous
    rows (axis 1) of TAKE_ROW_DTYPES and 1-D arrays of TAKE_DTYPES with int64 indices in range (what
    Paths.take passes); None for any other array (the caller's NumPy take: path_tracer.taken_with_room)."""
    index = np.asarray(index)
    if index.dtype != np.int64 or index.ndim != 1:
        return [None] * len(arrays)
    index = read_only(np.ascontiguousarray(index))
    out = []
    for a, axis in arrays:
        if a.flags.c_contiguous and a.ndim == 2 and axis == 1 and a.dtype in TAKE_ROW_DTYPES:
            rows = np.empty((a.shape[0], index.shape[0] + room), a.dtype)
            _take_rows(read_only(a), index, rows)
            out.append(rows)
        elif a.flags.c_contiguous and a.ndim == 1 and a.dtype in TAKE_DTYPES:
            values = np.empty(index.shape[0] + room, a.dtype)
            _take_1d(read_only(a), index, values)
            out.append(values)
        else:
            out.append(None)
    return out


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes."""
    from types import SimpleNamespace
    rows = np.ones((3, 3))
    ls = SimpleNamespace(direction=rows, normal=-rows, pdf=np.ones(3), distance=np.ones(3),
                         one_sided=np.ones(3, np.bool_), light=np.zeros(3, np.int64), radiance=rows)
    cos_x, _, valid = light_tests(rows, ls, True)
    for into in (None, (np.zeros((3, 4)), np.ones((3, 4)), 1, np.zeros(4, np.int32), None),
                 (np.zeros((3, 4)), np.ones((3, 4)), 1, np.zeros(4, np.int32), (1.0, np.inf))):
        lambert_light(valid, np.zeros(len(valid), np.bool_), cos_x, ls, np.ones(3), np.ones(1, np.bool_), True, rows,
                      into)
    flags = np.array([DIFFUSE_LOBE | REFLECTION_LOBE, DELTA_LOBE | TRANSMISSION_LOBE, DELTA_LOBE], np.int8)
    idx, delta = np.array([0, 2], np.int64), np.array([True, False, False])
    places, lights = emitter_lights(idx, delta, np.ones(3, np.int8), np.zeros(3, np.int64), np.zeros(1, np.int64),
                                    np.array([-1, 0, -1, -1, -1], np.int64))
    for mode in (0, 1, 2):
        for clamp in (None, (np.inf, 10.0)):
            add_emission(np.zeros((3, 3)), rows, idx, rows[:, :2], delta, np.ones(3), places, np.ones(len(places)),
                         mode, 1, np.zeros(3, np.int32), clamp)
            for le in (rows[:, :2], rows[:, :1]):
                background_light(rows, rows, idx, le, delta, np.ones(3), sampled(idx, delta), np.ones(1), mode, 1,
                                 np.zeros(3, np.int32), clamp)
    count_bounces(np.zeros((4, 3), np.int32), flags)
    facing(rows, rows, rows)
    for counts, rr_after in ((None, None), (np.zeros((4, 3), np.int32), np.ones(3))):
        final_groups(np.zeros(3, np.int32), 8, True, counts, None if counts is None else np.ones(4, np.int64),
                     rr_after, 3)
    for flag in (True, False):
        survivors(rows, np.zeros(3, np.int32), np.zeros(3, np.bool_), np.full(3, 0.5), 8, flag, flag, 3, rows,
                  np.ones(3), np.ones(3), rows, rows)
    for ng, rr_after in ((None, None), (rows, None), (None, np.ones(3)), (rows, np.ones(3))):
        survivors(rows, np.zeros(3, np.int32), np.zeros(3, np.bool_), np.full(3, 0.5), 8, True, True, 3, rows,
                  None, np.ones(3), rows, rows, (flags, np.zeros(3, np.int8), rows, ng), rr_after)
    take([(np.zeros((3, 3), dtype), 1) for dtype in TAKE_ROW_DTYPES] + [(np.zeros(3, dtype), 0) for dtype in TAKE_DTYPES],
         idx)
