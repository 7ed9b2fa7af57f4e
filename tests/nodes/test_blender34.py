"""Blender 3.4's variants against Cycles 3.4 (Debian's /usr/bin/blender, tests/nodes/flat_quad.py):
the legacy MixRGB in every 3.4 blend mode, the Mix node, Color Ramp of every interpolation (3.4's
table: 256 entries at i / 255), RGB Curves, Combine / Separate RGB and HSV, Hue/Saturation/Value
(3.4's fmodf hue), RGB to BW and Wavelength (3.4's working space), Blackbody, Math's Arctan2 and
Vector Math's Reflect, in one render.  Control: 5.0's ramp table does not pass in 3.4."""
import numpy as np
import pytest

from engine.nodes import color as nc
from engine.nodes import converter as cv
from engine.nodes import math as nm
from tests.nodes import flat_quad
from tests.nodes.nodetest import combine, ctx, inputs_of, math_node, worst
from tests.nodes.test_color import RAMPS, _node, _other_inputs, _set_curve, _set_ramp, colour_values, colours
from tests.nodes.test_converter import temperatures, wavelengths

V34 = (3, 4)
BLENDS_34 = sorted(set(nc.BLEND) - nc.LEGACY_MISSING_BLEND)


def build_legacy(nodes, links, coord):
    fac, c1, c2, a, b, c = colours(nodes, links, coord)
    out = {}
    for blend in BLENDS_34:
        _node(nodes, links, "ShaderNodeMixRGB", f"rgb_{blend}", out, {"Fac": fac, "Color1": c1, "Color2": c2},
              blend_type=blend, use_clamp=blend in ("ADD", "DODGE", "LINEAR_LIGHT"))
    for blend in ("MIX", "OVERLAY", "HUE", "SOFT_LIGHT"):
        _node(nodes, links, "ShaderNodeMix", f"mix_{blend}", out, {"Factor_Float": fac, "A_Color": c1, "B_Color": c2},
              "Result_Color", data_type="RGBA", blend_type=blend, clamp_factor=False)
    for i, (interpolation, mode, hue) in enumerate(RAMPS):
        node = _node(nodes, links, "ShaderNodeValToRGB", f"ramp_{i}", out, {"Fac": fac})
        _set_ramp(node.color_ramp, interpolation, mode, hue)
        flat_quad.keep(f"ramp_{i}", node)
    node = _node(nodes, links, "ShaderNodeRGBCurve", "rgbcurve_EXTRAPOLATED", out, {"Fac": 0.8, "Color": c1})
    m = node.mapping
    _set_curve(m.curves[0], [(0.0, 0.1), (0.4, 0.7), (1.0, 0.9)], "VECTOR")
    _set_curve(m.curves[3], [(0.0, 0.05), (0.5, 0.6), (1.0, 0.95)], "AUTO_CLAMPED")
    m.extend = "EXTRAPOLATED"
    m.update()
    flat_quad.keep("rgbcurve_EXTRAPOLATED", node)
    _node(nodes, links, "ShaderNodeHueSaturation", "hsv", out,
          {"Hue": c, "Saturation": 1.3, "Value": 0.9, "Fac": 0.8, "Color": c1})
    _node(nodes, links, "ShaderNodeCombineRGB", "combinergb", out, {"R": fac, "G": c, "B": b})
    _node(nodes, links, "ShaderNodeCombineHSV", "combinehsv", out, {"H": fac, "S": c, "V": b})
    for i, ch in enumerate("RGB"):
        _node(nodes, links, "ShaderNodeSeparateRGB", f"separatergb_{ch}", out, {"Image": c1}, output=i)
    for i, ch in enumerate("HSV"):
        _node(nodes, links, "ShaderNodeSeparateHSV", f"separatehsv_{ch}", out, {"Color": c1}, output=i)
    _node(nodes, links, "ShaderNodeRGBToBW", "bw", out, {"Color": c1})
    sep = nodes.new("ShaderNodeSeparateXYZ")              # the temperatures and wavelengths of test_converter
    links.new(coord, sep.inputs[0])
    x, y = sep.outputs[0], sep.outputs[1]
    mm = math_node
    kelvin = mm(nodes, links, "ADD", mm(nodes, links, "MULTIPLY_ADD", x, 7000.0, mm(nodes, links, "MULTIPLY", y, 300.0)), 7000.0)
    _node(nodes, links, "ShaderNodeBlackbody", "blackbody", out, {"Temperature": kelvin})
    wl = mm(nodes, links, "MULTIPLY_ADD", x, 230.0, mm(nodes, links, "MULTIPLY_ADD", y, 7.0, 575.0))
    _node(nodes, links, "ShaderNodeWavelength", "wavelength", out, {"Wavelength": wl})
    _node(nodes, links, "ShaderNodeMath", "atan2", out, {"Value": a, "Value_001": b}, operation="ARCTAN2")
    _node(nodes, links, "ShaderNodeVectorMath", "reflect", out,
          {"Vector": combine(nodes, links, a, b, c), "Vector_001": c2}, operation="REFLECT")
    return out


def _legacy_output(key, k, points, version=V34):
    fac, c1, c2, a, b, c = vals = colour_values(points)
    n = points.shape[1]
    kind = key.split("_")[0]
    if kind == "rgb":
        return nc.mix_rgb_kernel(inputs_of(k, {"Fac": fac, "Color1": c1, "Color2": c2}, n), k["props"], ctx(n, version))["Color"]
    if kind == "mix":
        return nc.mix_kernel(inputs_of(k, {"Factor_Float": fac, "A_Color": c1, "B_Color": c2}, n), k["props"],
                             ctx(n, version))["Result_Color"]
    if kind in ("ramp", "rgbcurve", "hsv"):
        kernel = {"ramp": nc.color_ramp_kernel, "rgbcurve": nc.rgb_curves_kernel, "hsv": nc.hue_saturation_kernel}[kind]
        return next(iter(kernel(_other_inputs(key, k, vals, n), k["props"], ctx(n, version)).values()))
    table = {
        "combinergb": (cv.combine_rgb_kernel, {"R": fac, "G": c, "B": b}, "Image"),
        "combinehsv": (cv.combine_hsv_kernel, {"H": fac, "S": c, "V": b}, "Color"),
        "separatergb": (cv.separate_rgb_kernel, {"Image": c1}, key[-1]),
        "separatehsv": (cv.separate_hsv_kernel, {"Color": c1}, key[-1]),
        "bw": (cv.rgb_to_bw_kernel, {"Color": c1}, "Val"),
        "blackbody": (cv.blackbody_kernel, {"Temperature": temperatures(points)}, "Color"),
        "wavelength": (cv.wavelength_kernel, {"Wavelength": wavelengths(points)}, "Color"),
        "atan2": (nm.math_kernel, {"Value": a, "Value_001": b}, "Value"),
        "reflect": (nm.vector_math_kernel, {"Vector": np.stack([a, b, c]), "Vector_001": c2}, "Vector"),
    }
    kernel, linked, output = table[kind]
    return kernel(inputs_of(k, linked, n), k["props"], ctx(n, version))[output]


@pytest.mark.slow
def test_blender34_variants_agree_with_cycles34():
    images, points, kept = flat_quad.render(build_legacy, blender="3.4", kept=True)
    errors = {key: worst(images[key], _legacy_output(key, k, points)) for key, k in kept.items()}
    bad = {k: e for k, e in errors.items() if e > 1.0}
    assert not bad, bad
    assert len(errors) == len(BLENDS_34) + 4 + len(RAMPS) + 1 + 1 + 2 + 6 + 1 + 2 + 2
    assert len(kept["ramp_0"]["props"]["table"]) == nc.RAMP_TABLE_SIZE
    # controls: 5.0's ramp table (257 entries) and 5.0's luminance do not pass in 3.4
    k = kept["ramp_0"]
    props = {key: v for key, v in k["props"].items() if key != "table"}
    fac = colour_values(points)[0]
    out = nc.color_ramp_kernel({"Fac": fac}, props, ctx(points.shape[1], (5, 0)))["Color"]
    assert worst(images["ramp_0"], out) > 100
    assert worst(images["bw"], _legacy_output("bw", kept["bw"], points, (5, 0))) > 10
