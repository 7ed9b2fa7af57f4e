"""The Image Texture node inside a node program (ShaderNodeTexImage; Cycles' svm_node_tex_image): its
Vector input projected to (u, v) (FLAT: (x, y); SPHERE and TUBE: Cycles' map_to_sphere / map_to_tube
of the vector remapped from [0, 1] to [-1, 1]; BOX: the three flat projections blended by the
object-space normal), looked up by the scene's images (the context's `images`: engine/materials/
textures.py TextureSet.sample, the lookup an Image Texture wired straight into a socket uses).

props: "texture" (index into Scene.textures; -1: no usable image, which reads Cycles' missing-image
magenta), "interpolation" (Linear / Closest), "extension", "projection", "projection_blend"."""
from __future__ import annotations

import numpy as np

MISSING = (1.0, 0.0, 1.0)         # Cycles' TEX_IMAGE_MISSING_R, _G, _B


def map_to_sphere(co):
    x, y, z = co
    length = np.sqrt(x * x + y * y + z * z)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where((x == 0.0) & (y == 0.0), 0.0, 0.5 - np.arctan2(x, y) / (2.0 * np.pi))
        v = 1.0 - np.arccos(np.clip(z / np.where(length > 0, length, 1.0), -1.0, 1.0)) / np.pi
    return np.where(length > 0, u, 0.0), np.where(length > 0, v, 0.0)


def map_to_tube(co):
    x, y, z = co
    length = np.sqrt(x * x + y * y)
    with np.errstate(divide="ignore", invalid="ignore"):
        safe = np.where(length > 0, length, 1.0)
        u = (1.0 - np.arctan2(x / safe, y / safe) / np.pi) * 0.5
    v = (z + 1.0) * 0.5
    return np.where(length > 0, u, 0.0), np.where(length > 0, v, 0.0)


def _sample(props, ctx, u, v, alpha):
    texture = int(props.get("texture", -1))
    if texture < 0:
        color = np.repeat(np.asarray(MISSING)[:, None], len(u), axis=1)
        return color, np.ones(len(u))
    return ctx.image().sample(texture, u, v, props.get("interpolation", "Linear"),
                              props.get("extension", "REPEAT"), alpha)


def box_weights(n, blend):
    """Cycles' svm_node_tex_image_box weights (3, N) of the X, Y, Z projections for object normals n:
    one texture near the corners of the triangle of |n| / sum |n|, two along its edges, three inside."""
    n = np.abs(n)
    n = n / np.maximum(n.sum(axis=0), 1e-300)
    x, y, z = n
    limit = 0.5 * (1.0 + blend)
    w = np.zeros_like(n)
    left = np.ones(x.shape, dtype=bool)

    def zone(mask):
        nonlocal left
        mask = mask & left
        left = left & ~mask
        return mask
    for axis, mask in ((0, (x > limit * (x + y)) & (x > limit * (x + z))),
                       (1, (y > limit * (x + y)) & (y > limit * (y + z))),
                       (2, (z > limit * (x + z)) & (z > limit * (y + z)))):
        w[axis][zone(mask)] = 1.0
    if blend > 0.0:
        with np.errstate(divide="ignore", invalid="ignore"):
            for (i, j), mask in (((0, 1), z < (1.0 - limit) * (y + x)), ((1, 2), x < (1.0 - limit) * (y + z)),
                                 ((0, 2), y < (1.0 - limit) * (x + z))):
                m = zone(mask)
                t = np.clip((n[i][m] / (n[i][m] + n[j][m]) - 0.5 * (1.0 - blend)) / blend, 0.0, 1.0)
                w[i][m], w[j][m] = t, 1.0 - t
            m = left
            w[:, m] = ((2.0 - limit) * n[:, m] + (limit - 1.0)) / (2.0 * limit - 1.0)
    else:
        w[0][left] = 1.0
    return w


def image_texture(inputs, props, ctx):
    co = inputs["Vector"]
    projection = props.get("projection", "FLAT")
    alpha = "Alpha" in (props.get("_outputs") or ("Color", "Alpha"))
    if projection == "SPHERE":
        u, v = map_to_sphere(co * 2.0 - 1.0)
    elif projection == "TUBE":
        u, v = map_to_tube(co * 2.0 - 1.0)
    elif projection == "BOX":
        signed = ctx.attr("object_normal")
        w = box_weights(signed, float(props.get("projection_blend", 0.0)))
        color, a = np.zeros((3, ctx.n)), np.zeros(ctx.n)
        # Cycles' maps, "so that no textures are flipped": X (y or 1 - y, z), Y (x or 1 - x, z), Z (y or 1 - y, x).
        maps = ((np.where(signed[0] < 0.0, 1.0 - co[1], co[1]), co[2]),
                (np.where(signed[1] > 0.0, 1.0 - co[0], co[0]), co[2]),
                (np.where(signed[2] > 0.0, 1.0 - co[1], co[1]), co[0]))
        for axis, (mu, mv) in enumerate(maps):
            sel = np.flatnonzero(w[axis] > 0.0)
            if len(sel):
                c, al = _sample(props, ctx, mu.take(sel), mv.take(sel), alpha)
                color[:, sel] += w[axis].take(sel) * c
                a[sel] += w[axis].take(sel) * al
        return {"Color": color, "Alpha": a}
    else:
        u, v = co[0], co[1]
    color, a = _sample(props, ctx, u, v, alpha)
    return {"Color": color, "Alpha": a}


KERNELS = {"ShaderNodeTexImage": image_texture}
