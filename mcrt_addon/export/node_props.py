"""The properties of shader nodes whose settings are not plain RNA values: Color Ramp and the RGB /
Vector / Float Curves nodes.  `special_props(node)` gives them as plain data for the node programs
the exporter compiles (its generic property capture calls it first and adds the node's plain enum /
bool / number properties), None for every other node.

Cycles does not evaluate a ramp or a curve per shading point: it bakes a table in Blender (Blender's
own ColorRamp.evaluate / CurveMapping.evaluate) and interpolates it (engine/nodes/color.py).  The
props carry that table, baked here with the same calls at the same positions, so the kernels agree
with Cycles exactly; they also carry the elements / points, for reading and for scene files written by
hand (engine/nodes/color.py bakes a ramp from its elements when the table is absent).

Color Ramp (ShaderNodeValToRGB):
    {"elements": [(position, (r, g, b, a)), ...],        # sorted by position
     "interpolation": "LINEAR" | "EASE" | "CARDINAL" | "B_SPLINE" | "CONSTANT",
     "color_mode": "RGB" | "HSV" | "HSL",
     "hue_interpolation": "NEAR" | "FAR" | "CW" | "CCW",
     "table": [(r, g, b, a), ...]}                       # Cycles' table: 257 rows (Blender 3.x: 256)

RGB Curves / Vector Curves / Float Curve (ShaderNodeRGBCurve / VectorCurve / FloatCurve):
    {"curves": [{"points": [(x, y, handle_type), ...], "extend": "EXTRAPOLATED" | "HORIZONTAL"}, ...],
                                   # R, G, B, C (combined) for RGB Curves; X, Y, Z; the one Float curve
     "extend": "EXTRAPOLATED" | "HORIZONTAL",
     "extrapolate": bool,          # Cycles' flag: extend == "EXTRAPOLATED"
     "black_level": (r, g, b), "white_level": (r, g, b),  # RGB Curves only; Cycles ignores them
     "use_clip": bool, "clip_min_x", "clip_min_y", "clip_max_x", "clip_max_y": float,
     "min_x": float, "max_x": float,   # the table's range: the first and last point x over the curves
     "table": [(r, g, b), ...] or [v, ...]}  # Cycles' table over [min_x, max_x]; RGB Curves: the
                                              # R, G, B curves applied after the C curve
Tables are lists of floats (float32 values, as Cycles stores them), so a scene file keeps them.
"""
import numpy as np

RAMP_TABLE_SIZE = 256       # Cycles' RAMP_TABLE_SIZE
CURVE_NODES = {"ShaderNodeRGBCurve": 4, "ShaderNodeVectorCurve": 3, "ShaderNodeFloatCurve": 1}


def special_props(node):
    """The Color Ramp or curve mapping of `node` as plain data (module doc), or None."""
    kind = node.bl_idname
    if kind == "ShaderNodeValToRGB":
        return color_ramp_props(node.color_ramp)
    if kind in CURVE_NODES:
        return curve_props(node.mapping, CURVE_NODES[kind])
    return None


def table_positions(blender_version=None):
    """Cycles' table positions (float32) for the running Blender: 257 at i / 256 since 4.0, 256 at
    i / 255 in 3.x (engine/nodes/color.py table_positions)."""
    if blender_version is None:
        import bpy
        blender_version = bpy.app.version
    if tuple(blender_version)[:2] < (4, 0):
        return np.arange(RAMP_TABLE_SIZE, dtype=np.float32) / np.float32(RAMP_TABLE_SIZE - 1)
    return np.arange(RAMP_TABLE_SIZE + 1, dtype=np.float32) / np.float32(RAMP_TABLE_SIZE)


def _f32(values):
    return [float(v) for v in np.asarray(values, dtype=np.float32)]


def color_ramp_props(ramp, positions=None):
    positions = table_positions() if positions is None else positions
    elements = sorted(((float(e.position), tuple(float(c) for c in e.color)) for e in ramp.elements),
                      key=lambda e: e[0])
    table = [tuple(_f32(ramp.evaluate(float(x)))) for x in positions]
    return {"elements": elements, "interpolation": ramp.interpolation, "color_mode": ramp.color_mode,
            "hue_interpolation": ramp.hue_interpolation, "table": table}


def curve_props(mapping, count, positions=None):
    """A curve mapping's props; `count` curves feed Cycles' table (4 for RGB Curves: R, G, B and C)."""
    positions = table_positions() if positions is None else positions
    curves = list(mapping.curves)[:count]
    lo = float(min(c.points[0].location[0] for c in curves))
    hi = float(max(c.points[len(c.points) - 1].location[0] for c in curves))
    mapping.update()                    # Cycles: BKE_curvemapping_changed_all, then the missing tables
    mapping.initialize()
    span = np.float32(hi) - np.float32(lo)
    xs = positions * span + np.float32(lo)       # min + i / size * range, in float32
    if count == 4:                                # RGB Curves: R, G, B of the combined curve C
        c = [mapping.evaluate(curves[3], float(x)) for x in xs]
        table = [tuple(_f32([mapping.evaluate(curves[k], float(v)) for k in range(3)])) for v in c]
    elif count == 3:
        table = [tuple(_f32([mapping.evaluate(curves[k], float(x)) for k in range(3)])) for x in xs]
    else:
        table = _f32([mapping.evaluate(curves[0], float(x)) for x in xs])
    props = {
        "curves": [{"points": [(float(p.location[0]), float(p.location[1]), p.handle_type) for p in c.points],
                    "extend": mapping.extend} for c in curves],
        "extend": mapping.extend,
        "extrapolate": mapping.extend == "EXTRAPOLATED",
        "use_clip": bool(mapping.use_clip),
        "clip_min_x": float(mapping.clip_min_x), "clip_min_y": float(mapping.clip_min_y),
        "clip_max_x": float(mapping.clip_max_x), "clip_max_y": float(mapping.clip_max_y),
        "min_x": lo, "max_x": hi, "table": table,
    }
    if count == 4:
        props["black_level"] = tuple(float(v) for v in mapping.black_level)
        props["white_level"] = tuple(float(v) for v in mapping.white_level)
    return props
