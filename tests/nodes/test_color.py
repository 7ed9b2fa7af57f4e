"""engine/nodes/color.py against Cycles 5.0 on the flat quad (tests/nodes/flat_quad.py): Mix (float,
vector, non-uniform vector, colour in every blend mode, clamped factor / result), the legacy MixRGB,
Color Ramp (every interpolation, RGB / HSV / HSL with each hue interpolation), RGB / Vector / Float
Curves (extrapolated and horizontal), Hue/Saturation/Value, Invert, Gamma, Bright/Contrast, per
pixel to float32 rounding, with the tables mcrt_addon/export/node_props.py bakes.  Controls: a wrong
blend formula, and a ramp table of Blender 3.4's size, do not pass.  Fast tests: the colour-space
round trips and the ramp baked from its elements."""
import numpy as np
import pytest

from engine.nodes import color as nc
from tests.nodes import flat_quad
from tests.nodes.nodetest import F32, combine, ctx, inputs_of, math_node, scalars, sock, worst

BLENDS = sorted(nc.BLEND)
RAMPS = [("LINEAR", "RGB", "NEAR"), ("EASE", "RGB", "NEAR"), ("CONSTANT", "RGB", "NEAR"),
         ("B_SPLINE", "RGB", "NEAR"), ("CARDINAL", "RGB", "NEAR"), ("LINEAR", "HSV", "NEAR"),
         ("LINEAR", "HSV", "FAR"), ("LINEAR", "HSL", "CW"), ("EASE", "HSL", "CCW")]
ELEMENTS = [(0.1, (0.9, 0.1, 0.2, 1.0)), (0.35, (0.2, 0.8, 0.3, 0.5)), (0.6, (0.1, 0.2, 0.9, 0.8)),
            (0.85, (1.0, 0.9, 0.1, 0.2))]


def colours(nodes, links, coord):
    """Sockets fac = 0.75x + 0.5, c1 = (0.625x + 0.5, 0.625y + 0.5, c), c2 = (0.5y + 0.5, 0.75 - 0.5x, 0.25b + 0.4)."""
    sep = nodes.new("ShaderNodeSeparateXYZ")
    links.new(coord, sep.inputs[0])
    x, y = sep.outputs[0], sep.outputs[1]
    a, b, c = scalars(nodes, links, coord)
    fac = math_node(nodes, links, "MULTIPLY_ADD", x, 0.75, 0.5)
    c1 = combine(nodes, links, math_node(nodes, links, "MULTIPLY_ADD", x, 0.625, 0.5),
                 math_node(nodes, links, "MULTIPLY_ADD", y, 0.625, 0.5), c)
    c2 = combine(nodes, links, math_node(nodes, links, "MULTIPLY_ADD", y, 0.5, 0.5),
                 math_node(nodes, links, "MULTIPLY_ADD", x, -0.5, 0.75),
                 math_node(nodes, links, "MULTIPLY_ADD", b, 0.25, 0.4))
    return fac, c1, c2, a, b, c


def colour_values(points):
    x, y = points[0].astype(F32), points[1].astype(F32)
    a = x * F32(3.0)
    b = y * F32(2.0) + F32(0.3)
    c = x * F32(0.5) + (y * F32(0.25) + F32(0.2))
    fac = x * F32(0.75) + F32(0.5)
    c1 = np.stack([x * F32(0.625) + F32(0.5), y * F32(0.625) + F32(0.5), c])
    c2 = np.stack([y * F32(0.5) + F32(0.5), x * F32(-0.5) + F32(0.75), b * F32(0.25) + F32(0.4)])
    return [v.astype(np.float64) for v in (fac, c1, c2, a, b, c)]


def _node(nodes, links, kind, key, out, linked, output=0, **props):
    node = nodes.new(kind)
    for name, value in props.items():
        setattr(node, name, value)
    for identifier, value in linked.items():
        s = sock(node, identifier)
        if isinstance(value, (int, float, tuple)):
            s.default_value = value
        else:
            links.new(value, s)
    flat_quad.keep(key, node)
    out[key] = node.outputs[output] if isinstance(output, int) else sock(node, output, outputs=True)
    return node


def build_mix(nodes, links, coord):
    fac, c1, c2, a, b, c = colours(nodes, links, coord)
    out = {}
    for blend in BLENDS:
        _node(nodes, links, "ShaderNodeMix", f"mix_{blend}", out, {"Factor_Float": fac, "A_Color": c1, "B_Color": c2},
              "Result_Color", data_type="RGBA", blend_type=blend)
        _node(nodes, links, "ShaderNodeMixRGB", f"rgb_{blend}", out, {"Fac": fac, "Color1": c1, "Color2": c2},
              blend_type=blend, use_clamp=blend in ("ADD", "DODGE", "LINEAR_LIGHT"))
    for blend in ("MIX", "SCREEN", "OVERLAY", "LINEAR_LIGHT"):
        _node(nodes, links, "ShaderNodeMix", f"mixu_{blend}", out, {"Factor_Float": fac, "A_Color": c1, "B_Color": c2},
              "Result_Color", data_type="RGBA", blend_type=blend, clamp_factor=False, clamp_result=True)
    for clamp in (False, True):
        _node(nodes, links, "ShaderNodeMix", f"float_{int(clamp)}", out, {"Factor_Float": fac, "A_Float": a, "B_Float": b},
              "Result_Float", data_type="FLOAT", clamp_factor=clamp)
        _node(nodes, links, "ShaderNodeMix", f"vector_{int(clamp)}", out,
              {"Factor_Float": fac, "A_Vector": c1, "B_Vector": c2}, "Result_Vector", data_type="VECTOR", clamp_factor=clamp)
        _node(nodes, links, "ShaderNodeMix", f"nonuniform_{int(clamp)}", out,
              {"Factor_Vector": c2, "A_Vector": c1, "B_Vector": c1 if False else c2}, "Result_Vector",
              data_type="VECTOR", factor_mode="NON_UNIFORM", clamp_factor=clamp)
    return out


def _mix_inputs(key, k, vals, n):
    fac, c1, c2, a, b, c = vals
    if key.startswith("rgb_"):
        return inputs_of(k, {"Fac": fac, "Color1": c1, "Color2": c2}, n)
    if key.startswith("float_"):
        return inputs_of(k, {"Factor_Float": fac, "A_Float": a, "B_Float": b}, n)
    if key.startswith("vector_"):
        return inputs_of(k, {"Factor_Float": fac, "A_Vector": c1, "B_Vector": c2}, n)
    if key.startswith("nonuniform_"):
        return inputs_of(k, {"Factor_Vector": c2, "A_Vector": c1, "B_Vector": c2}, n)
    return inputs_of(k, {"Factor_Float": fac, "A_Color": c1, "B_Color": c2}, n)


@pytest.mark.slow
def test_mix_agrees_with_cycles():
    images, points, kept = flat_quad.render(build_mix, kept=True)
    vals = colour_values(points)
    n = points.shape[1]
    errors = {}
    for key, k in kept.items():
        kernel = nc.mix_rgb_kernel if key.startswith("rgb_") else nc.mix_kernel
        out = kernel(_mix_inputs(key, k, vals, n), k["props"], ctx(n))
        errors[key] = worst(images[key], next(iter(out.values())))
    bad = {k: e for k, e in errors.items() if e > 1.0}
    assert not bad, bad
    assert len(errors) == 2 * len(BLENDS) + 4 + 6
    # control: Screen without its factor (1 - (1 - a)(1 - b)) does not pass
    fac, c1, c2 = vals[:3]
    assert worst(images["mix_SCREEN"], 1.0 - (1.0 - c1) * (1.0 - c2)) > 100


def _set_ramp(ramp, interpolation, mode, hue):
    ramp.interpolation, ramp.color_mode, ramp.hue_interpolation = interpolation, mode, hue
    els = ramp.elements
    while len(els) < len(ELEMENTS):
        els.new(0.5)
    for e, (pos, col) in zip(els, ELEMENTS):
        e.position, e.color = pos, col


def _set_curve(curve, points, handle=None):
    while len(curve.points) < len(points):
        curve.points.new(0.5, 0.5)
    for p, (x, y) in zip(curve.points, points):
        p.location = (x, y)
    if handle:
        curve.points[1].handle_type = handle


def build_ramps_curves(nodes, links, coord):
    fac, c1, c2, a, b, c = colours(nodes, links, coord)
    out = {}
    for i, (interpolation, mode, hue) in enumerate(RAMPS):
        node = _node(nodes, links, "ShaderNodeValToRGB", f"ramp_{i}", out, {"Fac": fac})
        _set_ramp(node.color_ramp, interpolation, mode, hue)
        out[f"ramp_{i}_alpha"] = node.outputs["Alpha"]
        flat_quad.keep(f"ramp_{i}", node)
    for extend in ("EXTRAPOLATED", "HORIZONTAL"):
        node = _node(nodes, links, "ShaderNodeRGBCurve", f"rgbcurve_{extend}", out, {"Fac": 0.8, "Color": c1})
        m = node.mapping
        _set_curve(m.curves[0], [(0.0, 0.1), (0.4, 0.7), (1.0, 0.9)], "VECTOR")
        _set_curve(m.curves[1], [(0.0, 0.0), (0.3, 0.2), (0.7, 0.9), (1.0, 1.0)])
        _set_curve(m.curves[2], [(0.1, 0.3), (1.0, 0.6)])
        _set_curve(m.curves[3], [(0.0, 0.05), (0.5, 0.6), (1.0, 0.95)], "AUTO_CLAMPED")
        m.extend = extend
        m.update()
        flat_quad.keep(f"rgbcurve_{extend}", node)
        node = _node(nodes, links, "ShaderNodeVectorCurve", f"veccurve_{extend}", out,
                     {"Fac": 0.9, "Vector": combine(nodes, links, a, b, c)})
        m = node.mapping
        _set_curve(m.curves[0], [(-1.0, -0.5), (0.2, 0.4), (1.0, 0.8)])
        _set_curve(m.curves[1], [(-1.0, 1.0), (1.0, -1.0)])
        _set_curve(m.curves[2], [(-0.5, -1.0), (0.0, 0.3), (0.8, 0.1)], "VECTOR")
        m.extend = extend
        m.update()
        flat_quad.keep(f"veccurve_{extend}", node)
        node = _node(nodes, links, "ShaderNodeFloatCurve", f"floatcurve_{extend}", out, {"Factor": 0.7, "Value": c})
        m = node.mapping
        _set_curve(m.curves[0], [(0.0, 0.2), (0.25, 0.9), (0.6, 0.1), (1.0, 0.6)])
        m.extend = extend
        m.update()
        flat_quad.keep(f"floatcurve_{extend}", node)
    _node(nodes, links, "ShaderNodeHueSaturation", "hsv", out,
          {"Hue": c, "Saturation": 1.3, "Value": 0.9, "Fac": 0.8, "Color": c1})
    _node(nodes, links, "ShaderNodeInvert", "invert", out, {"Fac": fac, "Color": c1})
    _node(nodes, links, "ShaderNodeGamma", "gamma", out, {"Color": c1, "Gamma": b})
    _node(nodes, links, "ShaderNodeBrightContrast", "bright", out, {"Color": c2, "Bright": c, "Contrast": 0.3})
    return out


def _other_inputs(key, k, vals, n):
    fac, c1, c2, a, b, c = vals
    linked = {"ramp": {"Fac": fac}, "rgbcurve": {"Color": c1}, "veccurve": {"Vector": np.stack([a, b, c])},
              "floatcurve": {"Value": c}, "hsv": {"Hue": c, "Color": c1}, "invert": {"Fac": fac, "Color": c1},
              "gamma": {"Color": c1, "Gamma": b}, "bright": {"Color": c2, "Bright": c}}[key.split("_")[0]]
    return inputs_of(k, linked, n)


KIND = {"ramp": nc.color_ramp_kernel, "rgbcurve": nc.rgb_curves_kernel, "veccurve": nc.vector_curves_kernel,
        "floatcurve": nc.float_curve_kernel, "hsv": nc.hue_saturation_kernel, "invert": nc.invert_kernel,
        "gamma": nc.gamma_kernel, "bright": nc.bright_contrast_kernel}


@pytest.mark.slow
def test_ramps_curves_and_colour_adjustments_agree_with_cycles():
    images, points, kept = flat_quad.render(build_ramps_curves, kept=True)
    vals = colour_values(points)
    n = points.shape[1]
    errors = {}
    for key, k in kept.items():
        out = KIND[key.split("_")[0]](_other_inputs(key, k, vals, n), k["props"], ctx(n))
        errors[key] = worst(images[key], next(iter(out.values())))
        if key.startswith("ramp_"):
            errors[key + "_alpha"] = worst(images[key + "_alpha"], out["Alpha"])
            assert len(k["props"]["table"]) == nc.RAMP_TABLE_SIZE + 1
    bad = {k: e for k, e in errors.items() if e > 1.0}
    assert not bad, bad
    assert len(errors) == 2 * len(RAMPS) + 6 + 4
    # the ramp baked here from its elements (no table) agrees too, to 1e-5
    for i in range(len(RAMPS)):
        k = kept[f"ramp_{i}"]
        props = {key: v for key, v in k["props"].items() if key != "table"}
        out = nc.color_ramp_kernel(_other_inputs(f"ramp_{i}", k, vals, n), props, ctx(n))
        assert worst(images[f"ramp_{i}"], out["Color"], rtol=1e-5, atol=1e-5) <= 1.0, RAMPS[i]
    # control: Blender 3.4's table (256 entries at i / 255) does not pass in 5.0
    k = kept["ramp_0"]
    props = {key: v for key, v in k["props"].items() if key != "table"}
    out = nc.color_ramp_kernel(_other_inputs("ramp_0", k, vals, n), props, ctx(n, (3, 4)))
    assert worst(images["ramp_0"], out["Color"]) > 100


# -- fast unit tests -------------------------------------------------------------------------------------
def test_colour_space_round_trips():
    rng = np.random.default_rng(7)
    rgb = rng.uniform(0.0, 1.0, (3, 200))
    assert np.allclose(nc.hsv_to_rgb(nc.rgb_to_hsv(rgb)), rgb)
    assert np.allclose(nc.hsl_to_rgb(nc.rgb_to_hsl(rgb)), rgb)
    grey = np.full((3, 1), 0.4)
    assert np.array_equal(nc.rgb_to_hsv(grey)[:, 0], [0.0, 0.0, 0.4])
    assert np.allclose(nc.rgb_to_hsv(np.array([[1.0], [0.0], [0.0]]))[:, 0], [0.0, 1.0, 1.0])
    assert np.allclose(nc.rgb_to_hsv(np.array([[0.0], [0.0], [1.0]]))[:, 0], [2.0 / 3.0, 1.0, 1.0])


def test_ramp_lookup_and_bake():
    table = np.array([[0.0], [1.0], [3.0]])
    f = np.array([-0.5, 0.25, 0.5, 0.75, 1.5])
    assert np.allclose(nc.ramp_lookup(table, f, True, False)[0], [0.0, 0.5, 1.0, 2.0, 3.0])
    assert np.allclose(nc.ramp_lookup(table, f, False, False)[0], [0.0, 0.0, 1.0, 1.0, 3.0])
    assert np.allclose(nc.ramp_lookup(table[:, 0], f, True, True), [-1.0, 0.5, 1.0, 2.0, 5.0])
    props = {"elements": [(0.0, (0.0, 0.0, 0.0, 1.0)), (1.0, (1.0, 1.0, 1.0, 1.0))], "interpolation": "LINEAR",
             "color_mode": "RGB", "hue_interpolation": "NEAR"}
    t5, t3 = nc.ramp_table(props, (5, 0)), nc.ramp_table(props, (3, 4))
    assert t5.shape == (257, 4) and t3.shape == (256, 4)
    assert np.allclose(t5[:, 0], np.arange(257) / 256.0) and np.allclose(t3[:, 0], np.arange(256) / 255.0)
    constant = dict(props, interpolation="CONSTANT",
                    elements=[(0.0, (0.0, 0.0, 0.0, 1.0)), (0.5, (1.0, 0.0, 0.0, 1.0))])
    out = nc.color_ramp_kernel({"Fac": np.array([0.25, 0.75])}, constant, ctx(2))["Color"]
    assert np.array_equal(out[0], [0.0, 1.0])
