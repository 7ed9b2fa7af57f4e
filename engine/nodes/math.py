"""Math, Vector Math, Map Range and Clamp nodes: Cycles' SVM kernels (svm_math, svm_vector_math,
svm_node_map_range, svm_node_vector_map_range, svm_node_clamp) over NumPy arrays.

Values are float64 (Cycles computes in float32: results agree to float32 rounding, except exactly at a
discontinuity such as floor(x) for an x that float32 rounds onto an integer).  The "safe" operations
return what Cycles returns where the plain one is undefined (division by zero gives 0, the power of a
negative base to a non-integer exponent 0, the logarithm of a non-positive number 0, ...).

Blender 3.4 and 4.x/5.0 differ (ctx.cycles_version): 3.4 has no Floored Modulo, no vector Power and
Sign; its Arctan2 of (0, -0) is pi (5.0: 0); its vector Reflect and Refract normalise the second
vector without the zero-length guard (a zero vector gives NaN; 5.0 leaves it zero).
"""
from __future__ import annotations

import numpy as np

from ..core.errors import SceneError

FLT_EPSILON = float(np.finfo(np.float32).eps)


def _legacy(ctx) -> bool:
    return tuple(getattr(ctx, "cycles_version", (5, 0)))[:2] < (4, 0)


def _input(inputs, key, ctx, vector=False, default=0.0):
    """inputs[key], or a constant where the exporter left out a socket the operation hides (Blender
    disables the unused sockets; Cycles reads them, but they do not change the result)."""
    value = inputs.get(key)
    if value is not None:
        return value
    return np.full((3, ctx.n) if vector else ctx.n, float(default))


# -- scalar helpers (util/math_base.h) ---------------------------------------------------------------
def safe_divide(a, b):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(b != 0.0, a / np.where(b != 0.0, b, 1.0), 0.0)


def safe_pow(a, b):
    """safe_powf: 0 for a negative base and a non-integer exponent; x^0 = 1 (also 0^0); 0^y = 0."""
    with np.errstate(all="ignore"):
        p = np.power(a, b)
    p = np.where(a == 0.0, 0.0, p)
    p = np.where(b == 0.0, 1.0, p)
    return np.where((a < 0.0) & (b != np.trunc(b)), 0.0, p)


def safe_log(a, b):
    with np.errstate(all="ignore"):
        out = safe_divide(np.log(np.where(a > 0.0, a, 1.0)), np.log(np.where(b > 0.0, b, 1.0)))
    return np.where((a <= 0.0) | (b <= 0.0), 0.0, out)


def safe_fmod(a, b):
    with np.errstate(all="ignore"):
        return np.where(b != 0.0, np.fmod(a, np.where(b != 0.0, b, 1.0)), 0.0)


def floored_modulo(a, b):
    with np.errstate(all="ignore"):
        return np.where(b != 0.0, a - np.floor(a / np.where(b != 0.0, b, 1.0)) * b, 0.0)


def wrap(value, hi, lo):
    """wrapf(value, max, min): value wrapped into [min, max); min where the range is empty."""
    r = hi - lo
    with np.errstate(all="ignore"):
        return np.where(r != 0.0, value - r * np.floor((value - lo) / np.where(r != 0.0, r, 1.0)), lo)


def pingpong(a, b):
    with np.errstate(all="ignore"):
        t = (a - b) / np.where(b != 0.0, b * 2.0, 1.0)
        return np.where(b != 0.0, np.abs((t - np.floor(t)) * b * 2.0 - b), 0.0)


def smooth_min(a, b, k):
    with np.errstate(all="ignore"):
        h = np.maximum(k - np.abs(a - b), 0.0) / np.where(k != 0.0, k, 1.0)
        return np.where(k != 0.0, np.minimum(a, b) - h * h * h * k * (1.0 / 6.0), np.minimum(a, b))


def compatible_sign(a):
    return np.where(a == 0.0, 0.0, np.where(a < 0.0, -1.0, 1.0))


def _clamp(v, lo, hi):
    return np.minimum(np.maximum(v, lo), hi)


# -- Math ----------------------------------------------------------------------------------------------
def _atan2(a, b, legacy):
    if legacy:
        return np.arctan2(a, b)
    return np.where((a == 0.0) & (b == 0.0), 0.0, np.arctan2(a, b))


def _inverse_sqrt(a):
    with np.errstate(all="ignore"):
        return np.where(a > 0.0, 1.0 / np.sqrt(np.where(a > 0.0, a, 1.0)), 0.0)


MATH = {
    "ADD": lambda a, b, c: a + b,
    "SUBTRACT": lambda a, b, c: a - b,
    "MULTIPLY": lambda a, b, c: a * b,
    "DIVIDE": lambda a, b, c: safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "POWER": lambda a, b, c: safe_pow(a, b),
    "LOGARITHM": lambda a, b, c: safe_log(a, b),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0.0)),
    "INVERSE_SQRT": lambda a, b, c: _inverse_sqrt(a),
    "ABSOLUTE": lambda a, b, c: np.abs(a),
    "EXPONENT": lambda a, b, c: np.exp(a),
    "MINIMUM": lambda a, b, c: np.fmin(a, b),
    "MAXIMUM": lambda a, b, c: np.fmax(a, b),
    "LESS_THAN": lambda a, b, c: (a < b).astype(np.float64),
    "GREATER_THAN": lambda a, b, c: (a > b).astype(np.float64),
    "SIGN": lambda a, b, c: compatible_sign(a),
    "COMPARE": lambda a, b, c: ((a == b) | (np.abs(a - b) <= np.maximum(c, FLT_EPSILON))).astype(np.float64),
    "SMOOTH_MIN": lambda a, b, c: smooth_min(a, b, c),
    "SMOOTH_MAX": lambda a, b, c: -smooth_min(-a, -b, c),
    "ROUND": lambda a, b, c: np.floor(a + 0.5),
    "FLOOR": lambda a, b, c: np.floor(a),
    "CEIL": lambda a, b, c: np.ceil(a),
    "TRUNC": lambda a, b, c: np.trunc(a),
    "FRACT": lambda a, b, c: a - np.floor(a),
    "MODULO": lambda a, b, c: safe_fmod(a, b),
    "FLOORED_MODULO": lambda a, b, c: floored_modulo(a, b),
    "WRAP": lambda a, b, c: wrap(a, b, c),
    "SNAP": lambda a, b, c: np.floor(safe_divide(a, b)) * b,
    "PINGPONG": lambda a, b, c: pingpong(a, b),
    "SINE": lambda a, b, c: np.sin(a),
    "COSINE": lambda a, b, c: np.cos(a),
    "TANGENT": lambda a, b, c: np.tan(a),
    "ARCSINE": lambda a, b, c: np.arcsin(_clamp(a, -1.0, 1.0)),
    "ARCCOSINE": lambda a, b, c: np.arccos(_clamp(a, -1.0, 1.0)),
    "ARCTANGENT": lambda a, b, c: np.arctan(a),
    "SINH": lambda a, b, c: np.sinh(a),
    "COSH": lambda a, b, c: np.cosh(a),
    "TANH": lambda a, b, c: np.tanh(a),
    "RADIANS": lambda a, b, c: a * (np.pi / 180.0),
    "DEGREES": lambda a, b, c: a * (180.0 / np.pi),
}
LEGACY_MISSING_MATH = frozenset({"FLOORED_MODULO"})


def math_value(operation: str, a, b, c, legacy: bool = False):
    """svm_math(operation, a, b, c) over arrays."""
    if operation == "ARCTAN2":
        return _atan2(a, b, legacy)
    if operation not in MATH or (legacy and operation in LEGACY_MISSING_MATH):
        raise SceneError(f"Math node: operation {operation!r} is not one of Cycles' "
                         f"{'3.4' if legacy else '5.0'} operations")
    with np.errstate(all="ignore"):
        return MATH[operation](a, b, c)


def math_kernel(inputs, props, ctx):
    a, b, c = (_input(inputs, key, ctx) for key in ("Value", "Value_001", "Value_002"))
    value = math_value(props.get("operation", "ADD"), a, b, c, _legacy(ctx))
    if props.get("use_clamp", False):                 # MathNode::expand: a Clamp node (0, 1) after
        value = _clamp(value, 0.0, 1.0)
    return {"Value": value}


# -- Vector Math ---------------------------------------------------------------------------------------
def dot(a, b):
    return (a * b).sum(axis=0)


def length(a):
    return np.sqrt(dot(a, a))


def safe_normalize(a):
    t = length(a)
    with np.errstate(all="ignore"):
        return np.where(t != 0.0, a / np.where(t != 0.0, t, 1.0), a)


def cross(a, b):
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _project(a, b):
    ll = dot(b, b)
    with np.errstate(all="ignore"):
        return np.where(ll != 0.0, dot(a, b) / np.where(ll != 0.0, ll, 1.0), 0.0) * b


def _reflect(a, n):
    return a - 2.0 * n * dot(a, n)


def _refract(a, n, eta):
    d = dot(n, a)
    k = 1.0 - eta * eta * (1.0 - d * d)
    with np.errstate(all="ignore"):
        r = eta * a - (eta * d + np.sqrt(np.maximum(k, 0.0))) * n
    return np.where(k < 0.0, 0.0, r)


def _normalize_unsafe(a):
    with np.errstate(all="ignore"):
        return a / length(a)


VECTOR_OPS = {   # (a, b, c, scale, legacy) -> vector rows or a float (N,)
    "ADD": lambda a, b, c, s, L: a + b,
    "SUBTRACT": lambda a, b, c, s, L: a - b,
    "MULTIPLY": lambda a, b, c, s, L: a * b,
    "DIVIDE": lambda a, b, c, s, L: safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c, s, L: a * b + c,
    "CROSS_PRODUCT": lambda a, b, c, s, L: cross(a, b),
    "PROJECT": lambda a, b, c, s, L: _project(a, b),
    "REFLECT": lambda a, b, c, s, L: _reflect(a, _normalize_unsafe(b) if L else safe_normalize(b)),
    "REFRACT": lambda a, b, c, s, L: _refract(a, _normalize_unsafe(b) if L else safe_normalize(b), s),
    "FACEFORWARD": lambda a, b, c, s, L: np.where(dot(c, b) < 0.0, a, -a),
    "DOT_PRODUCT": lambda a, b, c, s, L: dot(a, b),
    "DISTANCE": lambda a, b, c, s, L: length(a - b),
    "LENGTH": lambda a, b, c, s, L: length(a),
    "SCALE": lambda a, b, c, s, L: a * s,
    "NORMALIZE": lambda a, b, c, s, L: safe_normalize(a),
    "ABSOLUTE": lambda a, b, c, s, L: np.abs(a),
    "POWER": lambda a, b, c, s, L: safe_pow(a, b),
    "SIGN": lambda a, b, c, s, L: compatible_sign(a),
    "MINIMUM": lambda a, b, c, s, L: np.minimum(a, b),
    "MAXIMUM": lambda a, b, c, s, L: np.maximum(a, b),
    "FLOOR": lambda a, b, c, s, L: np.floor(a),
    "CEIL": lambda a, b, c, s, L: np.ceil(a),
    "FRACTION": lambda a, b, c, s, L: a - np.floor(a),
    "MODULO": lambda a, b, c, s, L: safe_fmod(a, b),
    "WRAP": lambda a, b, c, s, L: wrap(a, b, c),
    "SNAP": lambda a, b, c, s, L: np.floor(safe_divide(a, b)) * b,
    "SINE": lambda a, b, c, s, L: np.sin(a),
    "COSINE": lambda a, b, c, s, L: np.cos(a),
    "TANGENT": lambda a, b, c, s, L: np.tan(a),
}
LEGACY_MISSING_VECTOR = frozenset({"POWER", "SIGN"})


def vector_math_kernel(inputs, props, ctx):
    op = props.get("operation", "ADD")
    legacy = _legacy(ctx)
    if op not in VECTOR_OPS or (legacy and op in LEGACY_MISSING_VECTOR):
        raise SceneError(f"Vector Math node: operation {op!r} is not one of Cycles' "
                         f"{'3.4' if legacy else '5.0'} operations")
    a, b, c = (_input(inputs, key, ctx, vector=True) for key in ("Vector", "Vector_001", "Vector_002"))
    s = _input(inputs, "Scale", ctx, default=1.0)
    with np.errstate(all="ignore"):
        r = VECTOR_OPS[op](a, b, c, s, legacy)
    if r.ndim == 1:                                   # a float operation: no vector (Cycles leaves it unset)
        return {"Vector": np.zeros((3, r.shape[0])), "Value": r}
    return {"Vector": r, "Value": np.zeros(r.shape[1])}


# -- Map Range -----------------------------------------------------------------------------------------
def _smoothstep(e0, e1, x):
    with np.errstate(all="ignore"):
        t = (x - e0) / (e1 - e0)
    return np.where(x < e0, 0.0, np.where(x >= e1, 1.0, (3.0 - 2.0 * t) * (t * t)))


def _smootherstep(e0, e1, x):
    t = _clamp(safe_divide(x - e0, e1 - e0), 0.0, 1.0)
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def _range_clamp(v, lo, hi):
    """ClampNode RANGE: clamp into [lo, hi], or [hi, lo] where lo > hi."""
    return np.where(lo > hi, _clamp(v, hi, lo), _clamp(v, lo, hi))


def map_range_float(value, from_min, from_max, to_min, to_max, steps, interpolation, clamp):
    span = from_max - from_min
    with np.errstate(all="ignore"):
        linear = (value - from_min) / np.where(span != 0.0, span, 1.0)
        if interpolation == "LINEAR":
            factor = linear
        elif interpolation == "STEPPED":
            factor = np.where(steps > 0.0, np.floor(linear * (steps + 1.0)) / np.where(steps > 0.0, steps, 1.0), 0.0)
        elif interpolation == "SMOOTHSTEP":
            factor = np.where(from_min > from_max, 1.0 - _smoothstep(from_max, from_min, value),
                              _smoothstep(from_min, from_max, value))
        elif interpolation == "SMOOTHERSTEP":
            factor = np.where(from_min > from_max, 1.0 - _smootherstep(from_max, from_min, value),
                              _smootherstep(from_min, from_max, value))
        else:
            raise SceneError(f"Map Range node: interpolation {interpolation!r} is not one of Cycles'")
        result = np.where(span != 0.0, to_min + factor * (to_max - to_min), 0.0)
    if clamp:                                         # MapRangeNode::expand: a Clamp node (range) after
        result = _range_clamp(result, to_min, to_max)
    return result


def map_range_vector(value, from_min, from_max, to_min, to_max, steps, interpolation, clamp):
    factor = safe_divide(value - from_min, from_max - from_min)
    with np.errstate(all="ignore"):
        if interpolation == "LINEAR":
            pass
        elif interpolation == "STEPPED":
            factor = np.where(steps > 0.0, np.floor(factor * (steps + 1.0)) / np.where(steps > 0.0, steps, 1.0), 0.0)
        elif interpolation == "SMOOTHSTEP":
            f = _clamp(factor, 0.0, 1.0)
            factor = (3.0 - 2.0 * f) * (f * f)
        elif interpolation == "SMOOTHERSTEP":
            f = _clamp(factor, 0.0, 1.0)
            factor = f * f * f * (f * (f * 6.0 - 15.0) + 10.0)
        else:
            raise SceneError(f"Map Range node: interpolation {interpolation!r} is not one of Cycles'")
        result = to_min + factor * (to_max - to_min)
    if clamp and interpolation in ("LINEAR", "STEPPED"):   # Cycles ignores Clamp for the smooth ones
        result = _range_clamp(result, to_min, to_max)
    return result


def map_range_kernel(inputs, props, ctx):
    interpolation = props.get("interpolation_type", "LINEAR")
    clamp = bool(props.get("clamp", True))
    if props.get("data_type", "FLOAT") == "FLOAT_VECTOR":
        v = map_range_vector(inputs["Vector"], inputs["From_Min_FLOAT3"], inputs["From_Max_FLOAT3"],
                             inputs["To_Min_FLOAT3"], inputs["To_Max_FLOAT3"],
                             _input(inputs, "Steps_FLOAT3", ctx, vector=True, default=4.0), interpolation, clamp)
        return {"Vector": v, "Result": np.zeros(v.shape[1])}
    r = map_range_float(inputs["Value"], inputs["From Min"], inputs["From Max"], inputs["To Min"],
                        inputs["To Max"], _input(inputs, "Steps", ctx, default=4.0), interpolation, clamp)
    return {"Result": r, "Vector": np.zeros((3, r.shape[0]))}


# -- Clamp ---------------------------------------------------------------------------------------------
def clamp_kernel(inputs, props, ctx):
    v, lo, hi = inputs["Value"], inputs["Min"], inputs["Max"]
    if props.get("clamp_type", "MINMAX") == "RANGE":
        return {"Result": _range_clamp(v, lo, hi)}
    return {"Result": _clamp(v, lo, hi)}


KERNELS = {
    "ShaderNodeMath": math_kernel,
    "ShaderNodeVectorMath": vector_math_kernel,
    "ShaderNodeMapRange": map_range_kernel,
    "ShaderNodeClamp": clamp_kernel,
}
