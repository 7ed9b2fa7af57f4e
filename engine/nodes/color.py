"""Colour nodes: Mix (and 3.4's MixRGB), Color Ramp, RGB / Vector / Float Curves, Hue/Saturation/Value,
Invert, Gamma, Brightness/Contrast: Cycles' SVM kernels (svm_mix and its blend modes, the ramp
table lookups of kernel/svm/ramp.h, svm_node_hsv, svm_node_invert, svm_math_gamma_color,
svm_brightness_contrast) over NumPy arrays; colours are linear RGB rows (3, N).

Color Ramp and the Curves nodes are tables, as Cycles bakes them: Blender evaluates the ramp or curve
mapping at RAMP_TABLE_SIZE + 1 evenly spaced positions (Blender 3.4: RAMP_TABLE_SIZE positions) and
the kernel interpolates the table linearly (a Constant ramp: the entry at or below).  The exporter
(mcrt_addon/export/node_props.py) puts the table Blender computed into the node's props ("table"),
so a ramp or curve agrees with Cycles exactly, whatever its interpolation, colour mode or handles.  A
ramp without a table (a hand-written scene file) is baked here from its elements, a port of Blender's
BKE_colorband_evaluate (all interpolations and the RGB / HSV / HSL colour modes); a curve without a
table is an error.

The colour conversions (rgb_to_hsv ...) are Cycles' util/color.h, shared with engine/nodes/converter.py.
"""
from __future__ import annotations

import functools

import numpy as np

from ..core.errors import SceneError

RAMP_TABLE_SIZE = 256


def _legacy(ctx) -> bool:
    return tuple(getattr(ctx, "cycles_version", (5, 0)))[:2] < (4, 0)


def table_positions(cycles_version) -> np.ndarray:
    """Where Cycles' ramp / curve tables sample the ramp or curve (as fractions of its range):
    RAMP_TABLE_SIZE + 1 positions i / RAMP_TABLE_SIZE since Blender 4.0, RAMP_TABLE_SIZE positions
    i / (RAMP_TABLE_SIZE - 1) in 3.x."""
    if tuple(cycles_version)[:2] < (4, 0):
        return np.arange(RAMP_TABLE_SIZE, dtype=np.float32) / np.float32(RAMP_TABLE_SIZE - 1)
    return np.arange(RAMP_TABLE_SIZE + 1, dtype=np.float32) / np.float32(RAMP_TABLE_SIZE)


# -- colour spaces (Cycles util/color.h) -------------------------------------------------------------
def rgb_to_hsv(rgb):
    r, g, b = rgb
    cmax = np.fmax(r, np.fmax(g, b))
    cmin = np.minimum(r, np.minimum(g, b))
    delta = cmax - cmin
    with np.errstate(all="ignore"):
        s = np.where(cmax != 0.0, delta / np.where(cmax != 0.0, cmax, 1.0), 0.0)
        d = np.where(s != 0.0, delta, 1.0)
        cr, cg, cb = (cmax - r) / d, (cmax - g) / d, (cmax - b) / d
    h = np.where(r == cmax, cb - cg, np.where(g == cmax, 2.0 + cr - cb, 4.0 + cg - cr)) / 6.0
    h = np.where(h < 0.0, h + 1.0, h)
    h = np.where(s != 0.0, h, 0.0)
    return np.stack([h, s, cmax])


def hsv_to_rgb(hsv):
    h, s, v = hsv
    h = np.where(h == 1.0, 0.0, h) * 6.0
    i = np.floor(h)
    f = h - i
    p = v * (1.0 - s)
    q = v * (1.0 - s * f)
    t = v * (1.0 - s * (1.0 - f))
    choices = [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v)]
    out = []
    for ch in range(3):
        c = np.select([i == k for k in range(5)], [choice[ch] for choice in choices], default=(v, p, q)[ch])
        out.append(np.where(s != 0.0, c, v))
    return np.stack(out)


def rgb_to_hsl(rgb):
    r, g, b = rgb
    cmax = np.fmax(r, np.fmax(g, b))
    cmin = np.minimum(r, np.minimum(g, b))
    lum = np.minimum(1.0, (cmax + cmin) / 2.0)
    delta = cmax - cmin
    grey = cmax == cmin
    with np.errstate(all="ignore"):
        d = np.where(grey, 1.0, delta)
        s = np.where(lum > 0.5, delta / np.where(grey, 1.0, 2.0 - cmax - cmin),
                     delta / np.where(grey, 1.0, cmax + cmin))
        h = np.where(cmax == r, (g - b) / d + np.where(g < b, 6.0, 0.0),
                     np.where(cmax == g, (b - r) / d + 2.0, (r - g) / d + 4.0))
    h = np.where(grey, 0.0, h) / 6.0
    return np.stack([h, np.where(grey, 0.0, s), lum])


def hsl_to_rgb(hsl):
    h, s, lum = hsl
    nr = np.clip(np.abs(h * 6.0 - 3.0) - 1.0, 0.0, 1.0)
    ng = np.clip(2.0 - np.abs(h * 6.0 - 2.0), 0.0, 1.0)
    nb = np.clip(2.0 - np.abs(h * 6.0 - 4.0), 0.0, 1.0)
    chroma = (1.0 - np.abs(2.0 * lum - 1.0)) * s
    return np.stack([(nr - 0.5) * chroma + lum, (ng - 0.5) * chroma + lum, (nb - 0.5) * chroma + lum])


# -- Mix blend modes (Cycles kernel/svm/color_util.h svm_mix) ----------------------------------------
def _interp(a, b, t):
    return a + t * (b - a)


def _overlay(t, c1, c2):
    tm = 1.0 - t
    return np.where(c1 < 0.5, c1 * (tm + 2.0 * t * c2), 1.0 - (tm + 2.0 * t * (1.0 - c2)) * (1.0 - c1))


def _divide(t, c1, c2):
    with np.errstate(all="ignore"):
        return np.where(c2 != 0.0, (1.0 - t) * c1 + t * c1 / np.where(c2 != 0.0, c2, 1.0), c1)


def _dodge(t, c1, c2):
    tmp = 1.0 - t * c2
    with np.errstate(all="ignore"):
        q = c1 / np.where(tmp > 0.0, tmp, 1.0)
    out = np.where(tmp <= 0.0, 1.0, np.where(q > 1.0, 1.0, q))
    return np.where(c1 != 0.0, out, c1)


def _burn(t, c1, c2):
    tmp = (1.0 - t) + t * c2
    with np.errstate(all="ignore"):
        q = 1.0 - (1.0 - c1) / np.where(tmp > 0.0, tmp, 1.0)
    return np.where(tmp <= 0.0, 0.0, np.clip(q, 0.0, 1.0))


def _hue(t, c1, c2):
    hsv2 = rgb_to_hsv(c2)
    hsv = rgb_to_hsv(c1)
    hsv[0] = hsv2[0]
    return np.where(hsv2[1] != 0.0, _interp(c1, hsv_to_rgb(hsv), t), c1)


def _saturation(t, c1, c2):
    hsv = rgb_to_hsv(c1)
    hsv2 = rgb_to_hsv(c2)
    keep = hsv[1] != 0.0
    hsv[1] = (1.0 - t) * hsv[1] + t * hsv2[1]
    return np.where(keep, hsv_to_rgb(hsv), c1)


def _value(t, c1, c2):
    hsv = rgb_to_hsv(c1)
    hsv2 = rgb_to_hsv(c2)
    hsv[2] = (1.0 - t) * hsv[2] + t * hsv2[2]
    return hsv_to_rgb(hsv)


def _color(t, c1, c2):
    hsv2 = rgb_to_hsv(c2)
    hsv = rgb_to_hsv(c1)
    hsv[0], hsv[1] = hsv2[0], hsv2[1]
    return np.where(hsv2[1] != 0.0, _interp(c1, hsv_to_rgb(hsv), t), c1)


def _soft_light(t, c1, c2):
    scr = 1.0 - (1.0 - c2) * (1.0 - c1)
    return (1.0 - t) * c1 + t * ((1.0 - c1) * c2 * c1 + c1 * scr)


BLEND = {   # Blender's blend_type -> svm_mix(t, c1, c2); t is (N,), broadcast over the rows
    "MIX": lambda t, a, b: _interp(a, b, t),
    "ADD": lambda t, a, b: _interp(a, a + b, t),
    "MULTIPLY": lambda t, a, b: _interp(a, a * b, t),
    "SCREEN": lambda t, a, b: 1.0 - ((1.0 - t) + t * (1.0 - b)) * (1.0 - a),
    "OVERLAY": _overlay,
    "SUBTRACT": lambda t, a, b: _interp(a, a - b, t),
    "DIVIDE": _divide,
    "DIFFERENCE": lambda t, a, b: _interp(a, np.abs(a - b), t),
    "EXCLUSION": lambda t, a, b: np.maximum(_interp(a, a + b - 2.0 * a * b, t), 0.0),
    "DARKEN": lambda t, a, b: _interp(a, np.minimum(a, b), t),
    "LIGHTEN": lambda t, a, b: _interp(a, np.maximum(a, b), t),
    "DODGE": _dodge,
    "BURN": _burn,
    "HUE": _hue,
    "SATURATION": _saturation,
    "VALUE": _value,
    "COLOR": _color,
    "SOFT_LIGHT": _soft_light,
    "LINEAR_LIGHT": lambda t, a, b: a + t * (2.0 * b - 1.0),
}
LEGACY_MISSING_BLEND = frozenset({"EXCLUSION"})


def mix_colors(blend_type: str, t, c1, c2, legacy: bool = False):
    """svm_mix(blend_type, t, c1, c2): t (N,), colours rows (3, N)."""
    if blend_type not in BLEND or (legacy and blend_type in LEGACY_MISSING_BLEND):
        raise SceneError(f"Mix node: blend mode {blend_type!r} is not one of Cycles' "
                         f"{'3.4' if legacy else '5.0'} blend modes")
    with np.errstate(all="ignore"):
        return BLEND[blend_type](t, c1, c2)


def _saturate(x):
    return np.clip(x, 0.0, 1.0)


def mix_kernel(inputs, props, ctx):
    """ShaderNodeMix (3.4+): Cycles' MixFloat, MixVector, MixVectorNonUniform or MixColor node."""
    data_type = props.get("data_type", "FLOAT")
    clamp_factor = bool(props.get("clamp_factor", True))
    if data_type == "FLOAT":
        t = inputs["Factor_Float"]
        t = _saturate(t) if clamp_factor else t
        return {"Result_Float": inputs["A_Float"] * (1.0 - t) + inputs["B_Float"] * t}
    if data_type == "VECTOR":
        t = inputs["Factor_Vector"] if props.get("factor_mode", "UNIFORM") == "NON_UNIFORM" else inputs["Factor_Float"]
        t = _saturate(t) if clamp_factor else t
        return {"Result_Vector": inputs["A_Vector"] * (1.0 - t) + inputs["B_Vector"] * t}
    if data_type == "RGBA":
        t = inputs["Factor_Float"]
        t = _saturate(t) if clamp_factor else t
        result = mix_colors(props.get("blend_type", "MIX"), t, inputs["A_Color"], inputs["B_Color"], _legacy(ctx))
        if props.get("clamp_result", False):
            result = _saturate(result)
        return {"Result_Color": result}
    raise SceneError(f"Mix node: data type {data_type!r} has no Cycles shader node")


def mix_rgb_kernel(inputs, props, ctx):
    """ShaderNodeMixRGB (the legacy Mix): the factor is always clamped; Clamp clamps the result."""
    result = mix_colors(props.get("blend_type", "MIX"), _saturate(inputs["Fac"]), inputs["Color1"],
                        inputs["Color2"], _legacy(ctx))
    if props.get("use_clamp", False):
        result = _saturate(result)
    return {"Color": result}


# -- ramp tables (Cycles kernel/svm/ramp.h) ----------------------------------------------------------
def ramp_lookup(table, f, interpolate: bool, extrapolate: bool):
    """rgb_ramp_lookup / float_ramp_lookup: `table` (K, C) or (K,), f (N,) -> (C, N) or (N,)."""
    table = np.asarray(table, dtype=np.float64)
    k = table.shape[0]
    f = np.asarray(f, dtype=np.float64)
    scaled = np.clip(np.nan_to_num(f, nan=0.0), 0.0, 1.0) * (k - 1)
    i = np.clip(scaled.astype(np.int64), 0, k - 1)
    t = scaled - i
    a = table[i]
    if interpolate:
        b = table[np.minimum(i + 1, k - 1)]
        tt = t[:, None] if table.ndim == 2 else t
        a = np.where(tt > 0.0, (1.0 - tt) * a + tt * b, a)
    if extrapolate:
        lo, hi = f < 0.0, f > 1.0
        ff = f[:, None] if table.ndim == 2 else f
        below = table[0] + (table[0] - table[1]) * (-ff) * (k - 1)
        above = table[-1] + (table[-1] - table[-2]) * (ff - 1.0) * (k - 1)
        lo_, hi_ = (lo[:, None], hi[:, None]) if table.ndim == 2 else (lo, hi)
        a = np.where(lo_, below, np.where(hi_, above, a))
    return a.T if table.ndim == 2 else a


def _hue_interp(mode, mfac, fac, h1, h2):
    """Blender's colorband_hue_interp (hue_interpolation NEAR / FAR / CW / CCW)."""
    h1 = h1 if h1 < 1.0 else h1 - 1.0
    h2 = h2 if h2 < 1.0 else h2 - 1.0
    if mode == "NEAR":
        way = 1 if (h1 < h2 and h2 - h1 > 0.5) else 2 if (h1 > h2 and h2 - h1 < -0.5) else 0
    elif mode == "FAR":
        way = 1 if (h1 == h2 or (h1 < h2 and h2 - h1 < 0.5)) else 2 if (h1 > h2 and h2 - h1 > -0.5) else 0
    elif mode == "CCW":
        way = 2 if h1 > h2 else 0
    elif mode == "CW":
        way = 1 if h1 < h2 else 0
    else:
        raise SceneError(f"Color Ramp: hue interpolation {mode!r} is not one of Blender's")
    if way == 0:
        return mfac * h1 + fac * h2
    h = mfac * (h1 + 1.0) + fac * h2 if way == 1 else mfac * h1 + fac * (h2 + 1.0)
    return h if h < 1.0 else h - 1.0


def _spline_weights(t, kind):
    t2, t3 = t * t, t * t * t
    if kind == "CARDINAL":
        fc = 0.71
        return (-fc * t3 + 2.0 * fc * t2 - fc * t, (2.0 - fc) * t3 + (fc - 3.0) * t2 + 1.0,
                (fc - 2.0) * t3 + (3.0 - 2.0 * fc) * t2 + fc * t, fc * t3 - fc * t2)
    return (-0.16666666 * t3 + 0.5 * t2 - 0.5 * t + 0.16666666, 0.5 * t3 - t2 + 0.66666666,
            -0.5 * t3 + 0.5 * t2 + 0.5 * t + 0.16666666, 0.16666666 * t3)


def colorband_evaluate(elements, interpolation: str, color_mode: str, hue_interpolation: str, x: float):
    """Blender's BKE_colorband_evaluate at one position: (r, g, b, a).  `elements` sorted by position."""
    data = [(float(p), np.asarray(c, dtype=np.float64)) for p, c in elements]
    if not data:
        raise SceneError("Color Ramp: no elements")
    ipo = interpolation if color_mode == "RGB" else "LINEAR"
    simple = ipo in ("LINEAR", "EASE", "CONSTANT")
    if len(data) == 1 or (x <= data[0][0] and simple):
        return data[0][1].copy()
    a = next((i for i, (p, _) in enumerate(data) if p > x), len(data))
    tot = len(data)
    if a == tot:
        left, right = data[a - 1], (1.0, data[a - 1][1])
    elif a == 0:
        left, right = (0.0, data[0][1]), data[0]
    else:
        left, right = data[a - 1], data[a]
    # Blender's names: cbd1 = right (the first element past x), cbd2 = left
    if (a == tot and simple) or ipo == "CONSTANT":
        return left[1].copy()
    if left[0] != right[0]:
        fac = (x - right[0]) / (left[0] - right[0])
    else:
        fac = 0.0 if a != tot else 1.0
    if ipo in ("B_SPLINE", "CARDINAL"):
        c0 = right[1] if a >= tot - 1 else data[a + 1][1]
        c3 = left[1] if a < 2 else data[a - 2][1]
        w = _spline_weights(min(max(fac, 0.0), 1.0), ipo)
        return np.clip(w[3] * c3 + w[2] * left[1] + w[1] * right[1] + w[0] * c0, 0.0, 1.0)
    if ipo == "EASE":
        fac = 3.0 * fac * fac - 2.0 * fac * fac * fac
    mfac = 1.0 - fac
    c1, c2 = right[1], left[1]
    if color_mode in ("HSV", "HSL"):
        to, back = (rgb_to_hsv, hsv_to_rgb) if color_mode == "HSV" else (rgb_to_hsl, hsl_to_rgb)
        h1, h2 = to(c1[:3, None])[:, 0], to(c2[:3, None])[:, 0]
        out = np.array([_hue_interp(hue_interpolation, mfac, fac, h1[0], h2[0]),
                        mfac * h1[1] + fac * h2[1], mfac * h1[2] + fac * h2[2]])
        return np.append(back(out[:, None])[:, 0], mfac * c1[3] + fac * c2[3])
    return mfac * c1 + fac * c2


def ramp_table(props, cycles_version=(5, 0)) -> np.ndarray:
    """The (K, 4) RGBA table Cycles interpolates: props["table"] when the exporter gave it, else baked
    from props["elements"] at table_positions(cycles_version)."""
    if props.get("table") is not None:
        return np.asarray(props["table"], dtype=np.float64).reshape(-1, 4)
    elements = tuple(sorted((float(p), tuple(float(v) for v in c)) for p, c in props.get("elements") or ()))
    return _baked_ramp(elements, props.get("interpolation", "LINEAR"), props.get("color_mode", "RGB"),
                       props.get("hue_interpolation", "NEAR"), tuple(cycles_version)[:2] < (4, 0))


@functools.lru_cache(maxsize=64)
def _baked_ramp(elements, interpolation, color_mode, hue_interpolation, legacy):
    positions = table_positions((3, 4) if legacy else (5, 0))
    table = np.array([colorband_evaluate(elements, interpolation, color_mode, hue_interpolation, float(x))
                      for x in positions])
    table.flags.writeable = False
    return table


def color_ramp_kernel(inputs, props, ctx):
    table = ramp_table(props, getattr(ctx, "cycles_version", (5, 0)))
    interpolate = props.get("interpolation", "LINEAR") != "CONSTANT"
    rgba = ramp_lookup(table, inputs["Fac"], interpolate, False)
    return {"Color": rgba[:3], "Alpha": rgba[3]}


def _curve_table(props, width):
    table = props.get("table")
    if table is None:
        raise SceneError("a Curves node without its table (the exporter bakes it from Blender's curve mapping)")
    return np.asarray(table, dtype=np.float64).reshape(-1, width) if width > 1 else np.asarray(table, dtype=np.float64)


def _curves(inputs, props, key):
    """svm_node_curves: each channel through its column of the table over [min_x, max_x]."""
    table = _curve_table(props, 3)
    lo, hi = float(props.get("min_x", 0.0)), float(props.get("max_x", 1.0))
    value, fac = inputs[key], inputs["Fac"]
    rel = (value - lo) / (hi - lo)
    extrapolate = bool(props.get("extrapolate", False))
    mapped = np.stack([ramp_lookup(table[:, ch], rel[ch], True, extrapolate) for ch in range(3)])
    return (1.0 - fac) * value + fac * mapped


def rgb_curves_kernel(inputs, props, ctx):
    return {"Color": _curves(inputs, props, "Color")}


def vector_curves_kernel(inputs, props, ctx):
    return {"Vector": _curves(inputs, props, "Vector")}


def float_curve_kernel(inputs, props, ctx):
    table = _curve_table(props, 1)
    lo, hi = float(props.get("min_x", 0.0)), float(props.get("max_x", 1.0))
    value, fac = inputs["Value"], inputs["Factor"]
    v = ramp_lookup(table, (value - lo) / (hi - lo), True, bool(props.get("extrapolate", False)))
    return {"Value": (1.0 - fac) * value + fac * v}


# -- Hue/Saturation/Value, Invert, Gamma, Brightness/Contrast ----------------------------------------
def hue_saturation_kernel(inputs, props, ctx):
    color, fac = inputs["Color"], inputs["Fac"]
    hsv = rgb_to_hsv(color)
    h = hsv[0] + inputs["Hue"] + 0.5
    hsv[0] = np.fmod(h, 1.0) if _legacy(ctx) else h - np.floor(h)     # 3.4: fmodf, 5.0: fractf
    hsv[1] = _saturate(hsv[1] * inputs["Saturation"])
    hsv[2] = hsv[2] * inputs["Value"]
    out = fac * hsv_to_rgb(hsv) + (1.0 - fac) * color
    return {"Color": np.maximum(out, 0.0)}


def invert_kernel(inputs, props, ctx):
    fac, color = inputs["Fac"], inputs["Color"]
    return {"Color": fac * (1.0 - color) + (1.0 - fac) * color}


def gamma_kernel(inputs, props, ctx):
    color, gamma = inputs["Color"], inputs["Gamma"]
    with np.errstate(all="ignore"):
        powered = np.where(color > 0.0, np.power(np.where(color > 0.0, color, 1.0), gamma), color)
    return {"Color": np.where(gamma == 0.0, 1.0, powered)}


def bright_contrast_kernel(inputs, props, ctx):
    contrast = inputs["Contrast"]
    a = 1.0 + contrast
    b = inputs["Bright"] - contrast * 0.5
    return {"Color": np.maximum(a * inputs["Color"] + b, 0.0)}


KERNELS = {
    "ShaderNodeMix": mix_kernel,
    "ShaderNodeMixRGB": mix_rgb_kernel,
    "ShaderNodeValToRGB": color_ramp_kernel,
    "ShaderNodeRGBCurve": rgb_curves_kernel,
    "ShaderNodeVectorCurve": vector_curves_kernel,
    "ShaderNodeFloatCurve": float_curve_kernel,
    "ShaderNodeHueSaturation": hue_saturation_kernel,
    "ShaderNodeInvert": invert_kernel,
    "ShaderNodeGamma": gamma_kernel,
    "ShaderNodeBrightContrast": bright_contrast_kernel,
}
