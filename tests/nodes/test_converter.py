"""engine/nodes/converter.py against Cycles 5.0 on the flat quad (tests/nodes/flat_quad.py): Combine /
Separate XYZ and Color (RGB, HSV, HSL), RGB to BW, Blackbody (below 800 K to above 12000 K) and
Wavelength (outside 380-780 nm too), per pixel to float32 rounding; the luminance weights and the
XYZ to RGB matrix are Cycles' (its OpenColorIO working space).  Control: Blender 3.4's luminance
weights do not pass in 5.0."""
import numpy as np
import pytest

from engine.nodes import converter as cv
from tests.nodes import flat_quad
from tests.nodes.nodetest import F32, ctx, inputs_of, math_node, worst
from tests.nodes.test_color import _node, colour_values, colours


def build_converters(nodes, links, coord):
    fac, c1, c2, a, b, c = colours(nodes, links, coord)
    sep = nodes.new("ShaderNodeSeparateXYZ")
    links.new(coord, sep.inputs[0])
    x, y = sep.outputs[0], sep.outputs[1]
    out = {}
    _node(nodes, links, "ShaderNodeCombineXYZ", "combinexyz", out, {"X": a, "Y": b, "Z": c})
    for i, axis in enumerate("XYZ"):
        _node(nodes, links, "ShaderNodeSeparateXYZ", f"separatexyz_{axis}", out, {"Vector": c2}, output=i)
    for mode in ("RGB", "HSV", "HSL"):
        _node(nodes, links, "ShaderNodeCombineColor", f"combinecolor_{mode}", out,
              {"Red": fac, "Green": c, "Blue": b}, mode=mode)
        for i, channel in enumerate(("Red", "Green", "Blue")):
            _node(nodes, links, "ShaderNodeSeparateColor", f"separatecolor_{mode}_{channel}", out, {"Color": c1},
                  output=i, mode=mode)
    _node(nodes, links, "ShaderNodeRGBToBW", "bw", out, {"Color": c1})
    kelvin = math_node(nodes, links, "MULTIPLY_ADD", x, 7000.0, math_node(nodes, links, "MULTIPLY", y, 300.0))
    _node(nodes, links, "ShaderNodeBlackbody", "blackbody", out, {"Temperature": math_node(nodes, links, "ADD", kelvin, 7000.0)})
    nm = math_node(nodes, links, "MULTIPLY_ADD", x, 230.0, math_node(nodes, links, "MULTIPLY_ADD", y, 7.0, 575.0))
    _node(nodes, links, "ShaderNodeWavelength", "wavelength", out, {"Wavelength": nm})
    return out


def temperatures(points):
    x, y = points[0].astype(F32), points[1].astype(F32)
    return (x * F32(7000.0) + y * F32(300.0) + F32(7000.0)).astype(np.float64)


def wavelengths(points):
    x, y = points[0].astype(F32), points[1].astype(F32)
    return (x * F32(230.0) + (y * F32(7.0) + F32(575.0))).astype(np.float64)


def _outputs(key, k, points, version=(5, 0)):
    fac, c1, c2, a, b, c = colour_values(points)
    n = points.shape[1]
    kind = key.split("_")[0]
    kernel, linked = {
        "combinexyz": (cv.combine_xyz_kernel, {"X": a, "Y": b, "Z": c}),
        "separatexyz": (cv.separate_xyz_kernel, {"Vector": c2}),
        "combinecolor": (cv.combine_color_kernel, {"Red": fac, "Green": c, "Blue": b}),
        "separatecolor": (cv.separate_color_kernel, {"Color": c1}),
        "bw": (cv.rgb_to_bw_kernel, {"Color": c1}),
        "blackbody": (cv.blackbody_kernel, {"Temperature": temperatures(points)}),
        "wavelength": (cv.wavelength_kernel, {"Wavelength": wavelengths(points)}),
    }[kind]
    out = kernel(inputs_of(k, linked, n), k["props"], ctx(n, version))
    if kind == "separatexyz":
        return out[key[-1]]
    if kind == "separatecolor":
        return out[key.split("_")[-1]]
    return next(iter(out.values()))


@pytest.mark.slow
def test_converters_agree_with_cycles():
    images, points, kept = flat_quad.render(build_converters, kept=True)
    errors = {key: worst(images[key], _outputs(key, k, points)) for key, k in kept.items()}
    bad = {k: e for k, e in errors.items() if e > 1.0}
    assert not bad, bad
    assert len(errors) == 1 + 3 + 3 * 4 + 3
    t, nm = temperatures(points), wavelengths(points)
    assert t.min() < 800.0 and t.max() > 12000.0 and nm.min() < 380.0 and nm.max() > 780.0
    # control: 3.4's luminance weights do not pass in 5.0
    assert worst(images["bw"], _outputs("bw", kept["bw"], points, (3, 4))) > 10


def test_working_space_constants():
    y5, y3 = cv.luminance_weights((5, 0)), cv.luminance_weights((3, 4))
    assert np.allclose(y5, [0.2126390, 0.7151687, 0.0721923], atol=1e-7)
    assert np.allclose(y3, [0.2126729, 0.7151522, 0.0721750], atol=1e-7)
    for version in ((5, 0), (3, 4)):
        white = cv.xyz_to_rgb(cv.RGB_TO_XYZ[cv._space(version)] @ np.ones((3, 1)), version)
        assert np.allclose(white, 1.0)
    assert np.allclose(cv.XYZ_TO_RGB["blender4"][0], [3.2409699, -1.5373832, -0.4986108], atol=1e-6)


def test_blackbody_and_wavelength_ends():
    t = np.array([500.0, 799.0, 12000.0, 20000.0])
    rgb = cv.blackbody_rec709(t)
    assert np.allclose(rgb[:, 0], cv.BLACKBODY_COLD) and np.allclose(rgb[:, 2], cv.BLACKBODY_HOT)
    out = cv.wavelength_kernel({"Wavelength": np.array([300.0, 379.0, 500.0, 781.0])}, {}, ctx(4))["Color"]
    assert not out[:, [0, 3]].any() and out[:, 2].max() > 0.0
