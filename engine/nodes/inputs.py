"""Input nodes as Cycles evaluates them (its kernel/svm/tex_coord.h, geometry.h, mapping.h, fresnel.h,
light_path.h): Texture Coordinate, Geometry, UV Map, Mapping, Value, RGB, Object Info, Layer Weight,
Fresnel, Light Path, Attribute.  Hit attributes come from the NodeContext (engine/nodes/context.py);
Window is the point's place in the camera's frame (context.py camera_window); outputs Cycles gives that
are not modelled here (Pointiness, Tangent, Object Info's Color) are named by the exporter (mcrt_addon/export/node_graph.py) and read 0 (Pointiness 0.5)."""
from __future__ import annotations

import functools

import numpy as np

from .context import Varying

CAMERA_RAY, DIFFUSE_RAY, GLOSSY_RAY, TRANSMISSION_RAY = 0, 1, 2, 3     # engine/integrators/path_tracer.py
SHADOW_RAY = 4                                                          # engine/nodes/context.py


def _dot(a, b):
    return (a * b).sum(axis=0)


def _normalize(v):
    length = np.sqrt(_dot(v, v))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(length > 0.0, v / np.where(length > 0.0, length, 1.0), 0.0)


def _outputs(getters, props):
    """The outputs the program reads (props "_outputs", which the exporter writes), each computed only
    then; without "_outputs" every output whose attributes the context has (Varying if none)."""
    wanted = props.get("_outputs")
    if wanted is not None:
        return {name: getters[name]() for name in wanted if name in getters}
    out = {}
    for name, get in getters.items():
        try:
            out[name] = get()
        except Varying:
            pass
    if not out:
        raise Varying(next(iter(getters)))
    return out


def _attr_or(ctx, name, fallback):
    """The attribute, or `fallback` where the hits lack it (never while folding: the mesh decides)."""
    try:
        return ctx.attr(name)
    except Varying:
        if fallback is None or ctx.folding:
            raise
        return fallback


def texture_coordinate(inputs, props, ctx):
    """ShaderNodeTexCoord; props "object_matrix_inverse" (4x4, the From object's world-to-object
    matrix; absent: the hit's own object)."""

    def lazy(name):
        return lambda: ctx.attr(name)
    getters = {"Generated": lazy("generated"), "Normal": lazy("object_normal"), "UV": lazy("uv"),
               "Camera": lazy("camera"), "Window": lambda: _attr_or(ctx, "window", ctx.zeros3())}
    inverse = props.get("object_matrix_inverse")
    if inverse is not None:
        m = np.asarray(inverse, dtype=np.float64)
        getters["Object"] = lambda: m[:3, :3] @ ctx.attr("position") + m[:3, 3:4]
    else:
        getters["Object"] = lazy("object")

    def reflection():
        i, n = ctx.attr("incoming"), ctx.attr("normal")
        return 2.0 * _dot(n, i) * n - i                  # -reflect(I, N)
    getters["Reflection"] = reflection
    return _outputs(getters, props)


def geometry(inputs, props, ctx):
    getters = {"Position": lambda: ctx.attr("position"), "Normal": lambda: ctx.attr("normal"),
               "True Normal": lambda: ctx.attr("true_normal"), "Incoming": lambda: ctx.attr("incoming"),
               "Backfacing": lambda: ctx.attr("backfacing"), "Pointiness": lambda: np.full(ctx.n, 0.5),
               "Tangent": ctx.zeros3, "Parametric": lambda: _attr_or(ctx, "parametric", ctx.zeros3()),
               "Random Per Island": ctx.zeros}
    return _outputs(getters, props)


def uv_map(inputs, props, ctx):
    return {"UV": ctx.attr("uv")}


def euler_matrix(euler):
    """Cycles' euler_to_transform (rows (3, 3, N) or (3, 3)): R = Rz Ry Rx."""
    x, y, z = euler
    cx, cy, cz = np.cos(x), np.cos(y), np.cos(z)
    sx, sy, sz = np.sin(x), np.sin(y), np.sin(z)
    return np.array([[cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz],
                     [cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz],
                     [-sy, cy * sx, cy * cx]])


@functools.lru_cache(maxsize=64)
def _one_rotation(x, y, z):
    """euler_matrix of one rotation as (3, 3, 1), made once per angles (read only)."""
    m = euler_matrix(np.array([x, y, z]))[:, :, None]
    m.flags.writeable = False
    return m


def _apply(m, v):                 # m (3, 3, N) or (3, 3, 1), v (3, N)
    if m.shape[2] == 1:
        return m[:, :, 0] @ v
    return np.einsum("ijn,jn->in", m, v)


def _apply_t(m, v):
    if m.shape[2] == 1:
        return m[:, :, 0].T @ v
    return np.einsum("jin,jn->in", m, v)


def _safe_divide(a, b):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(b != 0.0, a / np.where(b != 0.0, b, 1.0), 0.0)


def mapping(inputs, props, ctx):
    """ShaderNodeMapping (Cycles' svm_mapping): POINT, TEXTURE, VECTOR, NORMAL."""
    v = inputs["Vector"] if "Vector" in inputs else ctx.zeros3()
    loc = inputs["Location"] if "Location" in inputs else ctx.zeros3()
    euler = inputs["Rotation"] if "Rotation" in inputs else ctx.zeros3()
    if euler.shape[1] and (euler == euler[:, :1]).all():        # one rotation for every point (the usual)
        rot = _one_rotation(*(float(a) for a in euler[:, 0]))
    else:
        rot = euler_matrix(euler)
    scale = inputs["Scale"] if "Scale" in inputs else np.ones((3, ctx.n))
    kind = props.get("vector_type", "POINT")
    if kind == "POINT":
        out = _apply(rot, v * scale) + loc
    elif kind == "TEXTURE":
        out = _safe_divide(_apply_t(rot, v - loc), scale)
    elif kind == "VECTOR":
        out = _apply(rot, v * scale)
    else:
        out = _normalize(_apply(rot, _safe_divide(v, scale)))
    return {"Vector": out}


def value(inputs, props, ctx):
    return {"Value": np.full(ctx.n, float(props.get("value", 0.0)))}


def rgb(inputs, props, ctx):
    c = tuple(props.get("color", (0.5, 0.5, 0.5)))[:3]
    return {"Color": np.repeat(np.asarray(c, dtype=np.float64)[:, None], ctx.n, axis=1)}


def object_info(inputs, props, ctx):
    getters = {"Location": lambda: ctx.attr("object_location"), "Random": lambda: ctx.attr("object_random"),
               "Color": lambda: np.ones((3, ctx.n)), "Alpha": lambda: np.ones(ctx.n),
               "Object Index": ctx.zeros, "Material Index": ctx.zeros}
    return _outputs(getters, props)


def fresnel_dielectric_cos(cos, eta):
    """Cycles' fresnel_dielectric_cos: the unpolarised reflectance at |cos| for the IOR ratio eta, per
    point (1 beyond the critical angle); also the mix factors' (engine/materials/mix.py)."""
    c = np.abs(cos)
    g = eta * eta - 1.0 + c * c
    ok = g > 0.0
    g = np.sqrt(np.where(ok, g, 1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
        f = 0.5 * a * a * (1.0 + b * b)
    return np.where(ok, np.nan_to_num(f, nan=1.0), 1.0)


def _normal_input(inputs, ctx):
    n = inputs.get("Normal")
    return ctx.attr("normal") if n is None else n


def fresnel(inputs, props, ctx):
    eta = np.maximum(inputs.get("IOR", np.full(ctx.n, 1.45)), 1e-5)
    back = ctx.attr("backfacing") > 0.5
    cos = _dot(ctx.attr("incoming"), _normal_input(inputs, ctx))
    return {"Fac": fresnel_dielectric_cos(cos, np.where(back, 1.0 / eta, eta))}


def layer_weight(inputs, props, ctx):
    blend = inputs.get("Blend", np.full(ctx.n, 0.5))
    cos = _dot(ctx.attr("incoming"), _normal_input(inputs, ctx))
    out = {}
    wanted = props.get("_outputs")
    if wanted is None or "Fresnel" in wanted:
        eta = np.maximum(1.0 - blend, 1e-5)
        back = ctx.attr("backfacing") > 0.5
        out["Fresnel"] = fresnel_dielectric_cos(cos, np.where(back, eta, 1.0 / eta))
    if wanted is None or "Facing" in wanted:
        f = np.abs(cos)
        b = np.clip(blend, 0.0, 1.0 - 1e-5)
        exponent = np.where(b < 0.5, 2.0 * b, 0.5 / (1.0 - b))
        f = np.where(blend != 0.5, f ** exponent, f)
        out["Facing"] = 1.0 - f
    return out


def light_path(inputs, props, ctx):
    """ShaderNodeLightPath: the ray that found the hit (a light sample on an emitter: a shadow ray)."""
    kind = ctx.attr("ray_kind")
    depth = ctx.attr("ray_depth").astype(np.float64)
    as_float = lambda b: b.astype(np.float64)    # noqa: E731
    return {"Is Camera Ray": as_float(kind == CAMERA_RAY), "Is Shadow Ray": as_float(kind == SHADOW_RAY),
            "Is Diffuse Ray": as_float(kind == DIFFUSE_RAY), "Is Glossy Ray": as_float(kind == GLOSSY_RAY),
            "Is Singular Ray": ctx.zeros(),
            "Is Reflection Ray": as_float((kind == DIFFUSE_RAY) | (kind == GLOSSY_RAY)),
            "Is Transmission Ray": as_float(kind == TRANSMISSION_RAY),
            "Is Volume Scatter Ray": ctx.zeros(),
            "Ray Length": _attr_or(ctx, "ray_length", ctx.zeros()), "Ray Depth": depth,
            "Diffuse Depth": as_float(kind == DIFFUSE_RAY) * depth, "Glossy Depth": as_float(kind == GLOSSY_RAY) * depth,
            "Transparent Depth": ctx.zeros(), "Transmission Depth": as_float(kind == TRANSMISSION_RAY) * depth}


def attribute(inputs, props, ctx):
    """ShaderNodeAttribute of type GEOMETRY: a colour attribute (props "attribute_name"); other
    names read 0 as Cycles does for attributes a mesh lacks."""
    name = props.get("attribute_name", "")
    color = _attr_or(ctx, f"color:{name}", ctx.zeros3())
    return {"Color": color, "Vector": color, "Fac": (color * (1.0 / 3.0)).sum(axis=0), "Alpha": np.ones(ctx.n)}


KERNELS = {
    "ShaderNodeTexCoord": texture_coordinate,
    "ShaderNodeNewGeometry": geometry,
    "ShaderNodeUVMap": uv_map,
    "ShaderNodeMapping": mapping,
    "ShaderNodeValue": value,
    "ShaderNodeRGB": rgb,
    "ShaderNodeObjectInfo": object_info,
    "ShaderNodeFresnel": fresnel,
    "ShaderNodeLayerWeight": layer_weight,
    "ShaderNodeLightPath": light_path,
    "ShaderNodeAttribute": attribute,
}


def scale(inputs, props, ctx):
    """TNCG15Scale, the tracer's own node (no Blender node has it): an emission's colour x strength
    (mcrt_addon/export/node_graph.py scaled)."""
    return {"Color": inputs["Color"] * inputs["Strength"]}


KERNELS["TNCG15Scale"] = scale

# Constants these kernels broadcast (engine/nodes/registry.py broadcast_inputs): Mapping's Location and Scale
# meet the (3, N) Vector (always full: linked, or a full constant) in products and sums; Scale's Strength
# multiplies the full Color.  Not Rotation: a constant rotation with a NaN angle is not "uniform" to mapping's
# test, and given as one value it would take the matmul path instead of the per-point einsum (other bits).
BROADCAST_INPUTS = {"ShaderNodeMapping": ("Location", "Scale"), "TNCG15Scale": ("Strength",)}
