"""Normal Map and Bump nodes, and the normal a BSDF then uses, as Cycles computes them (its SVM
kernels svm_node_normal_map and svm_node_set_bump, and the closures' ensure_valid_reflection (3.4) /
maybe_ensure_valid_specular_reflection (4.x, 5.0)); docs/nodes.md "Bump and Normal Map".

Normals are rows (3, N), world space, on the viewer's side as the context's `normal` (Cycles' sd->N).

* Normal Map, Tangent space: the colour c in [0, 1] becomes 2 c - 1; the frame is the interpolated
  (unnormalised) tangent t of the UV map, the outward base normal n (the smooth normal, or the
  geometric one on flat faces) and B = sign x cross(n, t) with the corner's bitangent sign; N =
  normalize(c.x t + c.y B + c.z n), flipped on back faces.  Object space: the object's normal
  transform of c; World space: c.  Blender Object / World: c.y and c.z negated first.  Strength:
  Blender 4.x / 5.0 scale c.x, c.y and mix c.z towards 1 in tangent space (a linear blend with N
  elsewhere); Blender 3.x blends linearly in every space.
* Bump: the height h at the point and at P + dx, P + dy (the evaluator runs the Height input's
  nodes at the shifted points: ctx.shifted); with Rx = cross(dy, N), Ry = cross(N, dx),
  det = dx . Rx, N' = normalize(|det| N - distance sign(det) ((h_x - h) Rx + (h_y - h) Ry) / w),
  then normalize(strength N' + (1 - strength) N).  The offsets: `bump_offsets`.
"""
from __future__ import annotations

import numpy as np

from ..geometry.shading_normals import compiled
from ..geometry.shading_normals import ensure_valid_reflection as valid_reflection_3x

# Bump's offsets without a camera: this fraction of the ray length (bump_offsets).
BUMP_STEP = 1e-3
BUMP_FILTER_WIDTH = 0.1          # Blender 4.x / 5.0: the Bump node's Filter Width default (bump_filter_width)


def _dot(a, b):
    return (a * b).sum(axis=0)


def _cross(a, b):
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def safe_normalize(v):
    """v / |v|, 0 where |v| is 0 (Cycles' safe_normalize)."""
    length = np.sqrt(_dot(v, v))
    return np.where(length > 0.0, v / np.where(length > 0.0, length, 1.0), 0.0)


def tangent_space_normal(color, tangent, sign, base, backfacing, strength, cycles_version=(5, 0)):
    """Normal Map in tangent space: colour rows (3, N) in [0, 1], the interpolated tangent (3, N), the
    bitangent sign (N,), the outward base normal (3, N), backfacing (N,) bool, strength (N,);
    Blender 4.x / 5.0 apply the strength here (3.x: normal_map_strength afterwards)."""
    c = 2.0 * (np.asarray(color, dtype=np.float64) - 0.5)
    if tuple(cycles_version) >= (4, 0):
        c = np.stack([c[0] * strength, c[1] * strength, 1.0 + (c[2] - 1.0) * np.clip(strength, 0.0, 1.0)])
    bitangent = sign * _cross(base, tangent)
    n = safe_normalize(c[0] * tangent + c[1] * bitangent + c[2] * base)
    return np.where(backfacing, -n, n)


def normal_map(inputs, props, ctx):
    color = inputs["Color"]
    strength = inputs.get("Strength", np.ones(ctx.n))
    space = props.get("space", "TANGENT")
    shading = ctx.attr("normal")
    version = ctx.cycles_version
    linear = True
    if space == "TANGENT":
        c = np.asarray(color, dtype=np.float64)
        if compiled() is not None:           # a numba render (shading_normals.compiled_for): the same numbers
            from . import normals_jit
            if ctx.has("tangent_corners"):   # a scene's hits: the tangent frame made in the kernel's loop
                return {"Normal": normals_jit.corner_normal_map(c, strength, ctx.attr("tangent_corners"), shading,
                                                                ctx.attr("_towards"), version)}
            return {"Normal": normals_jit.tangent_normal_map(
                c, strength, ctx.attr("tangent"), ctx.attr("tangent_sign"), ctx.attr("tangent_base"),
                ctx.attr("backfacing") > 0.5, ctx.attr("has_tangent"), shading, version)}
        tangent, sign = ctx.attr("tangent"), ctx.attr("tangent_sign")
        has = ctx.attr("has_tangent")
        n = tangent_space_normal(c, tangent, sign, ctx.attr("tangent_base"), ctx.attr("backfacing") > 0.5, strength,
                                 version)
        n = np.where(has, n, shading)                      # no tangents (no UV map, a sphere): N
        linear = version < (4, 0)
    else:
        c = 2.0 * (np.asarray(color, dtype=np.float64) - 0.5)
        if space in ("BLENDER_OBJECT", "BLENDER_WORLD"):
            c = np.stack([c[0], -c[1], -c[2]])
        n = ctx.attr("object_to_world_normal")(c) if space in ("OBJECT", "BLENDER_OBJECT") else safe_normalize(c)
        n = np.where(ctx.attr("backfacing") > 0.5, -n, n)
    if linear:
        s = np.maximum(strength, 0.0)
        n = np.where(strength != 1.0, safe_normalize(shading + (n - shading) * s), n)
    bad = ~np.isfinite(n).all(axis=0) | ~(np.abs(n) > 0).any(axis=0)
    return {"Normal": np.where(bad, shading, n)}


def make_orthonormals(n):
    """Cycles' make_orthonormals: a = normalize((1, 1, 1) x n) (or (-1, 1, 1) x n), b = n x a."""
    a = np.stack([n[2] - n[1], n[0] - n[2], n[1] - n[0]])
    other = np.stack([n[2] - n[1], n[0] + n[2], -n[1] - n[0]])
    a = safe_normalize(np.where((n[0] != n[1]) | (n[0] != n[2]), a, other))
    return a, _cross(n, a)


def bump_offsets(ctx, ng):
    """(dx, dy) rows (3, N): Cycles' differential_from_compact(Ng, dP): make_orthonormals of the
    geometric normal `ng` times the compact footprint dP, the mean length of the ray's position
    differentials.  Camera rays (ray depth 0): the ray length times the mean length of the camera
    ray direction's one-pixel steps (|dD/dx| = pixel cos(theta) sqrt(1 - (D.right)^2), theta the
    angle off the view axis; likewise y) as Cycles' differential_transfer_compact.  Other rays: the
    ray length times the image centre's pixel size (Cycles carries the footprint along the path;
    the tracer keeps no ray differentials).  Without a camera: BUMP_STEP x the ray length."""
    distance = ctx.attr("ray_length") if ctx.has("ray_length") else np.ones(ctx.n)
    if ctx.has("camera_pixel"):
        right, up, forward, pixel = ctx.attr("camera_pixel")
        size = distance * pixel
        if ctx.has("ray_depth") and ctx.has("incoming"):
            d = -ctx.attr("incoming")
            cos = np.abs(_dot(d, forward))
            step = pixel * cos * 0.5 * (np.sqrt(np.maximum(1.0 - _dot(d, right) ** 2, 0.0))
                                        + np.sqrt(np.maximum(1.0 - _dot(d, up) ** 2, 0.0)))
            size = np.where(ctx.attr("ray_depth") == 0, distance * step, size)
    else:
        size = BUMP_STEP * distance
    a, b = make_orthonormals(ng)
    size = np.maximum(size, 1e-9)
    return a * size, b * size


def bump(inputs, props, ctx):
    shading = ctx.attr("normal")
    normal_in = inputs.get("Normal", shading)
    normal_in = safe_normalize(normal_in)
    height_at = inputs.get("_Height_at")
    if height_at is None:                      # a constant height: no perturbation
        return {"Normal": _valid_34(normal_in, ctx)}
    dx, dy = bump_offsets(ctx, ctx.attr("true_normal"))
    new = tuple(ctx.cycles_version) >= (4, 0)
    width = 1.0
    if new:                                  # Blender 4.x / 5.0: the node's Filter Width (a constant in Cycles)
        width = inputs["Filter Width"] if "Filter Width" in inputs else np.full(ctx.n, BUMP_FILTER_WIDTH)
        width = np.maximum(width, 1e-6)
    h_c = inputs["Height"]
    h_x, h_y = height_at(dx * width), height_at(dy * width)
    rx, ry = _cross(dy, normal_in), _cross(normal_in, dx)
    det = _dot(dx, rx)
    surfgrad = (h_x - h_c) * rx + (h_y - h_c) * ry
    distance = inputs.get("Distance", np.ones(ctx.n)) * (-1.0 if props.get("invert") else 1.0)
    strength = np.maximum(inputs.get("Strength", np.ones(ctx.n)), 0.0)
    out = safe_normalize(width * np.abs(det) * normal_in - distance * np.sign(det) * surfgrad)
    zero = ~(np.abs(out) > 0).any(axis=0)
    out = np.where(zero, normal_in, safe_normalize(strength * out + (1.0 - strength) * normal_in))
    return {"Normal": _valid_34(out, ctx)}


def _valid_34(n, ctx):
    """Blender 3.x's Bump node ends with ensure_valid_reflection (4.x / 5.0: only the closures)."""
    if tuple(ctx.cycles_version) >= (4, 0):
        return n
    return ensure_valid_reflection(ctx.attr("true_normal"), ctx.attr("incoming"), n, ctx.cycles_version)


def ensure_valid_reflection(ng, incoming, n, cycles_version=(5, 0)):
    """The shading normal n (3, N) raised towards ng just enough that the mirror reflection of the
    direction `incoming` (towards the viewer, on ng's side) lies above the surface (by
    min(0.9 cos, 0.01)): Cycles' ensure_valid_specular_reflection (4.x / 5.0: one root of the
    quartic) or 3.x's ensure_valid_reflection (both roots tried, ng when neither is valid:
    engine/geometry/shading_normals.py ensure_valid_reflection)."""
    n = np.asarray(n, dtype=np.float64)
    if tuple(cycles_version) < (4, 0):
        return valid_reflection_3x(ng, incoming, n)
    ni = _dot(n, incoming)
    r = 2.0 * ni * n - incoming
    iz = _dot(incoming, ng)
    threshold = np.minimum(0.9 * iz, 0.01)
    bad = _dot(ng, r) < threshold
    if not bad.any():
        return n
    idx = np.flatnonzero(bad)
    nb, gb, ib, t = n[:, idx], ng[:, idx], incoming[:, idx], threshold[idx]
    izb = iz[idx]
    x = nb - _dot(nb, gb) * gb
    length = np.sqrt(_dot(x, x))
    x = np.where(length > 0.0, x / np.where(length > 0.0, length, 1.0), nb)
    ix = _dot(ib, x)
    a = ix * ix + izb * izb
    a_safe = np.where(a > 0.0, a, 1.0)
    b = 2.0 * (a + izb * t)
    c = (t + izb) ** 2
    root = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
    nz2 = np.where(ix < 0.0, 0.25 * (b + root) / a_safe, 0.25 * (b - root) / a_safe)
    nx, nz = np.sqrt(np.maximum(1.0 - nz2, 0.0)), np.sqrt(np.maximum(nz2, 0.0))
    out = n.copy()
    out[:, idx] = nx * x + nz * gb
    return out


KERNELS = {"ShaderNodeNormalMap": normal_map, "ShaderNodeBump": bump}
# Inputs whose nodes the evaluator also runs at shifted points (engine/nodes/evaluator.py): the
# kernel gets inputs["_NAME_at"](offset rows (3, N)) -> the input's value there.
OFFSET_INPUTS = {"ShaderNodeBump": ("Height",)}


def bump_shadowing(smooth, n, wi, diffuse, is_eval, cycles_version=(5, 0)):
    """Cycles' bump_shadowing_term (its closures' factor where a Normal input changed the normal): (N,)
    for the directions wi (3, N) at hits with the smooth normal `smooth` (sd->N) and the BSDF's
    normal n; 1 where n is the smooth normal.  Blender 4.x / 5.0: 0 where cos(Ns, wi) cos(Ns, n) cos(n, wi) < 0 (wi on
    the wrong side) for light
    evaluations and diffuse samples, and diffuse lobes are softened by GGX's G1 of alpha^2 =
    tan^2(n, Ns) / 8 at cos(Ns, wi) (Conty Estevez et al.); Blender 3.x: diffuse lobes only, Chiang
    et al.'s g = cos(Ns, wi) / (cos(n, wi) cos(Ns, n)) smoothed as -g^3 + g^2 + g."""
    same = (smooth == n).all(axis=0)
    if tuple(cycles_version) >= (4, 0):
        # Only where the normal changed (per point: the same numbers as over every point).
        out = np.ones(len(same))
        changed = np.flatnonzero(~same)
        if len(changed) == len(same):
            out[:] = _bump_term_4x(smooth, n, wi, diffuse, is_eval)
        elif len(changed):
            diffuse = np.asarray(diffuse)
            out[changed] = _bump_term_4x(smooth.take(changed, axis=1), n.take(changed, axis=1),
                                         wi.take(changed, axis=1),
                                         diffuse.take(changed) if diffuse.ndim else diffuse, is_eval)
        return out
    cos_si, cos_sn, cos_ni = _dot(smooth, wi), _dot(smooth, n), _dot(n, wi)
    ng = np.where(cos_ni < 0.0, -smooth, smooth)
    den = cos_ni * _dot(ng, n)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(den != 0.0, _dot(ng, wi) / np.where(den != 0.0, den, 1.0), 0.0)
    term = np.where(g >= 1.0, 1.0, np.where(g < 0.0, 0.0, -g ** 3 + g * g + g))
    return np.where(same | ~diffuse, 1.0, term)


def _bump_term_4x(smooth, n, wi, diffuse, is_eval):
    """bump_shadowing's term under Blender 4.x / 5.0 at points whose normal n is not the smooth one."""
    cos_si, cos_sn, cos_ni = _dot(smooth, wi), _dot(smooth, n), _dot(n, wi)
    reject = (cos_si * cos_sn * cos_ni < 0.0) & (is_eval | diffuse)
    cos_i, cos_d = np.abs(cos_si), np.abs(cos_sn)
    with np.errstate(divide="ignore", invalid="ignore"):
        tan2_d = 1.0 / np.maximum(cos_d, 1e-300) ** 2 - 1.0
        alpha2 = np.clip(0.125 * tan2_d, 0.0, 1.0)
        c2 = np.maximum(cos_i, 1e-300) ** 2
        lam = 0.5 * (np.sqrt(1.0 + alpha2 * (1.0 - c2) / c2) - 1.0)
        soft = 1.0 / (1.0 + lam)
    soft = np.where((cos_d >= 1.0) | (cos_i >= 1.0), 1.0, np.where(cos_i < 1e-6, 0.0, soft))
    return np.where(reject, 0.0, np.where(diffuse, soft, 1.0))
