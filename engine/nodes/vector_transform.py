"""The Vector Transform node (ShaderNodeVectorTransform) as Cycles' svm_node_vector_transform (its
kernel/svm/vector_transform.h): a Point, Vector or Normal converted between World, Object (the hit's
object: NodeContext `object_to_world` / `world_to_object`, engine/nodes/context.py) and Camera space
(Cycles' camera space, x right, y up, z forward: `world_to_camera` / `camera_to_world`).

Points take the whole matrix, vectors its 3x3 part.  Normals: Blender 4.0 and later transform them
by the inverse transpose and normalise after each object or camera step (Cycles' fix of June 2023);
before 4.0 a normal is transformed as a vector and normalised once at the end, whatever the spaces.
Hits off any object (analytic spheres and quads) see the identity there, as Cycles' OBJECT_NONE."""
from __future__ import annotations

import numpy as np

from .context import Varying


def _normalize(v):
    length = np.sqrt((v * v).sum(axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(length > 0.0, v / np.where(length > 0.0, length, 1.0), 0.0)


def _per_hit(ctx, name):
    """(N, 3, 4) matrices of the hits (identity where the context has none, never while folding)."""
    try:
        return ctx.attr(name)
    except Varying:
        if ctx.folding:
            raise
        return np.tile(np.eye(4)[:3], (ctx.n, 1, 1))


def _camera(ctx, name):
    try:
        return np.asarray(ctx.attr(name), dtype=np.float64)
    except Varying:
        if ctx.folding:
            raise
        return np.eye(4)


def _apply(m, v, kind):
    """m: (N, 3, 4) per hit or (4, 4); kind "POINT" (with the translation) or "VECTOR"."""
    if m.ndim == 2:
        out = m[:3, :3] @ v
        return out + m[:3, 3:4] if kind == "POINT" else out
    out = np.einsum("nij,jn->in", m[:, :, :3], v)
    return out + m[:, :, 3].T if kind == "POINT" else out


def _apply_transposed(m, v):
    """The 3x3 part of m transposed, applied (Cycles' transform_direction_transposed)."""
    if m.ndim == 2:
        return m[:3, :3].T @ v
    return np.einsum("nji,jn->in", m[:, :, :3], v)


def vector_transform(inputs, props, ctx):
    v = np.asarray(inputs.get("Vector", ctx.zeros3()), dtype=np.float64)
    kind = props.get("vector_type", "VECTOR")
    source, target = props.get("convert_from", "WORLD"), props.get("convert_to", "OBJECT")
    if ctx.cycles_version < (4, 0):
        return {"Vector": _legacy(v, kind, source, target, ctx)}
    normal = kind == "NORMAL"

    def to_object(x):                          # world -> object
        if normal:                             # object_inverse_normal_transform: M^T n
            return _normalize(_apply_transposed(_per_hit(ctx, "object_to_world"), x))
        return _apply(_per_hit(ctx, "world_to_object"), x, kind)

    def from_object(x):                        # object -> world
        if normal:                             # object_normal_transform: inverse(M)^T n
            return _normalize(_apply_transposed(_per_hit(ctx, "world_to_object"), x))
        return _apply(_per_hit(ctx, "object_to_world"), x, kind)

    def to_camera(x):
        if normal:
            return _normalize(_apply_transposed(_camera(ctx, "camera_to_world"), x))
        return _apply(_camera(ctx, "world_to_camera"), x, kind)

    def from_camera(x):
        if normal:
            return _normalize(_apply_transposed(_camera(ctx, "world_to_camera"), x))
        return _apply(_camera(ctx, "camera_to_world"), x, kind)

    if source == "WORLD":
        v = to_camera(v) if target == "CAMERA" else to_object(v) if target == "OBJECT" else v
    elif source == "CAMERA":
        if target in ("WORLD", "OBJECT"):
            v = from_camera(v)
        if target == "OBJECT":
            v = to_object(v)
    elif source == "OBJECT":
        if target in ("WORLD", "CAMERA"):
            v = from_object(v)
        if target == "CAMERA":
            v = to_camera(v)
    return {"Vector": v}


def _legacy(v, kind, source, target, ctx):
    """Blender 3.x: a normal is a direction; one normalisation at the end."""
    step = "POINT" if kind == "POINT" else "VECTOR"
    if source == "WORLD" and target == "CAMERA":
        v = _apply(_camera(ctx, "world_to_camera"), v, step)
    elif source == "WORLD" and target == "OBJECT":
        v = _apply(_per_hit(ctx, "world_to_object"), v, step)
    elif source == "CAMERA" and target in ("WORLD", "OBJECT"):
        v = _apply(_camera(ctx, "camera_to_world"), v, step)
        if target == "OBJECT":
            v = _apply(_per_hit(ctx, "world_to_object"), v, step)
    elif source == "OBJECT" and target in ("WORLD", "CAMERA"):
        v = _apply(_per_hit(ctx, "object_to_world"), v, step)
        if target == "CAMERA":
            v = _apply(_camera(ctx, "world_to_camera"), v, step)
    return _normalize(v) if kind == "NORMAL" else v


KERNELS = {"ShaderNodeVectorTransform": vector_transform}
