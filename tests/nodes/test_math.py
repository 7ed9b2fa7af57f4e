"""engine/nodes/math.py against Cycles 5.0 on the flat quad (tests/nodes/flat_quad.py): every Math
and Vector Math operation, Map Range (float and vector, every interpolation, clamped or not) and
Clamp, per pixel to float32 rounding; a wrong formula (a control) does not pass.  Fast unit tests
check the safe operations' special cases."""
import numpy as np
import pytest

from engine.nodes import math as nm
from tests.nodes import flat_quad
from tests.nodes.nodetest import combine, ctx, inputs_of, scalar_values, scalars, sock, worst

MATH_OPS = sorted(nm.MATH) + ["ARCTAN2"]
VECTOR_OPS = sorted(nm.VECTOR_OPS)
VALUE_OPS = ("DOT_PRODUCT", "DISTANCE", "LENGTH")
MAP_TYPES = ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP")


def build_math(nodes, links, coord):
    a, b, c = scalars(nodes, links, coord)
    out = {}
    for op in MATH_OPS:
        for clamp in (False, True):
            if clamp and op not in ("SUBTRACT", "SINE", "POWER", "MULTIPLY_ADD"):
                continue
            node = nodes.new("ShaderNodeMath")
            node.operation, node.use_clamp = op, clamp
            for i, s in enumerate((a, b, c)):
                links.new(s, node.inputs[i])
            key = f"m_{op}_{int(clamp)}"
            flat_quad.keep(key, node)
            out[key] = node.outputs[0]
    return out


def build_vector_math(nodes, links, coord):
    a, b, c = scalars(nodes, links, coord)
    va = combine(nodes, links, a, b, c)
    vb = combine(nodes, links, c, a, b)
    vc = combine(nodes, links, b, c, 0.5)
    out = {}
    for op in VECTOR_OPS:
        node = nodes.new("ShaderNodeVectorMath")
        node.operation = op
        for i, s in enumerate((va, vb, vc)):
            links.new(s, node.inputs[i])
        links.new(b, node.inputs[3])                  # Scale (and Refract's IOR)
        flat_quad.keep(f"v_{op}", node)
        value_op = op in VALUE_OPS
        out[f"v_{op}"] = node.outputs[1 if value_op else 0]
    for kind in MAP_TYPES:
        for clamp in (False, True):
            node = nodes.new("ShaderNodeMapRange")
            node.interpolation_type, node.clamp = kind, clamp
            links.new(a, sock(node, "Value"))
            sock(node, "From Min").default_value = -1.0
            links.new(c, sock(node, "From Max"))
            sock(node, "To Min").default_value = 0.25
            links.new(b, sock(node, "To Max"))
            sock(node, "Steps").default_value = 3.0
            flat_quad.keep(f"r_{kind}_{int(clamp)}", node)
            out[f"r_{kind}_{int(clamp)}"] = node.outputs["Result"]
            node = nodes.new("ShaderNodeMapRange")
            node.data_type, node.interpolation_type, node.clamp = "FLOAT_VECTOR", kind, clamp
            links.new(va, sock(node, "Vector"))
            sock(node, "From_Min_FLOAT3").default_value = (-0.913, -0.5471, 0.0529)   # no exact step edges
            links.new(vc, sock(node, "From_Max_FLOAT3"))
            sock(node, "To_Min_FLOAT3").default_value = (0.25, 1.0, -0.5)
            links.new(vb, sock(node, "To_Max_FLOAT3"))
            sock(node, "Steps_FLOAT3").default_value = (3.0, 2.0, 5.0)
            flat_quad.keep(f"rv_{kind}_{int(clamp)}", node)
            out[f"rv_{kind}_{int(clamp)}"] = node.outputs["Vector"]
    for kind in ("MINMAX", "RANGE"):
        node = nodes.new("ShaderNodeClamp")
        node.clamp_type = kind
        links.new(a, sock(node, "Value"))
        links.new(b, sock(node, "Min"))
        links.new(c, sock(node, "Max"))
        flat_quad.keep(f"c_{kind}", node)
        out[f"c_{kind}"] = node.outputs[0]
    return out


def _abc(points):
    a, b, c = scalar_values(points)
    return a, b, c, np.stack([a, b, c]), np.stack([c, a, b]), np.stack([b, c, np.full_like(a, 0.5)])


def _math_errors(images, points, kept, version=(5, 0)):
    a, b, c, *_ = _abc(points)
    n = a.shape[0]
    errors = {}
    for key, k in kept.items():
        inputs = inputs_of(k, {"Value": a, "Value_001": b, "Value_002": c}, n)
        value = nm.math_kernel(inputs, k["props"], ctx(n, version))["Value"]
        errors[key] = worst(images[key], value)
    return errors


@pytest.mark.slow
def test_math_operations_agree_with_cycles():
    images, points, kept = flat_quad.render(build_math, kept=True)
    errors = _math_errors(images, points, kept)
    bad = {k: e for k, e in errors.items() if e > 1.0}
    assert not bad, bad
    assert len(errors) == len(MATH_OPS) + 4
    # control: PINGPONG computed as WRAP, SMOOTH_MIN without its smoothing, do not pass
    a, b, c, *_ = _abc(points)
    assert worst(images["m_PINGPONG_0"], nm.wrap(a, b, c)) > 100
    assert worst(images["m_SMOOTH_MIN_0"], np.minimum(a, b)) > 100


def _vector_errors(images, points, kept):
    a, b, c, va, vb, vc = _abc(points)
    n = a.shape[0]
    errors = {}
    for key, k in kept.items():
        if key.startswith("v_"):
            out = nm.vector_math_kernel(inputs_of(k, {"Vector": va, "Vector_001": vb, "Vector_002": vc, "Scale": b}, n),
                                        k["props"], ctx(n))
            errors[key] = worst(images[key], out["Value" if key[2:] in VALUE_OPS else "Vector"])
        elif key.startswith("r_"):
            out = nm.map_range_kernel(inputs_of(k, {"Value": a, "From Max": c, "To Max": b}, n), k["props"], ctx(n))
            errors[key] = worst(images[key], out["Result"])
        elif key.startswith("rv_"):
            out = nm.map_range_kernel(inputs_of(k, {"Vector": va, "From_Max_FLOAT3": vc, "To_Max_FLOAT3": vb}, n),
                                      k["props"], ctx(n))
            errors[key] = worst(images[key], out["Vector"])
        else:
            out = nm.clamp_kernel(inputs_of(k, {"Value": a, "Min": b, "Max": c}, n), k["props"], ctx(n))
            errors[key] = worst(images[key], out["Result"])
    return errors


@pytest.mark.slow
def test_vector_math_map_range_clamp_agree_with_cycles():
    images, points, kept = flat_quad.render(build_vector_math, kept=True)
    errors = _vector_errors(images, points, kept)
    bad = {k: e for k, e in errors.items() if e > 1.0}
    assert not bad, bad
    # control: Reflect about the unnormalised vector does not pass
    a, b, c, va, vb, vc = _abc(points)
    assert worst(images["v_REFLECT"], va - 2.0 * vb * (va * vb).sum(axis=0)) > 100


# -- fast unit tests -------------------------------------------------------------------------------------
def test_safe_operations_special_cases():
    z = np.array([0.0, 2.0, -8.0, -2.0, 0.0])
    w = np.array([0.0, 0.0, 1.0 / 3.0, 3.0, -1.0])
    assert np.array_equal(nm.safe_divide(np.ones(5), z), [0.0, 0.5, -0.125, -0.5, 0.0])
    assert np.array_equal(nm.safe_pow(z, w), [1.0, 1.0, 0.0, -8.0, 0.0])      # 0^0 = 1, (-8)^(1/3) = 0
    assert np.array_equal(nm.safe_log(z, np.full(5, 2.0)), [0.0, 1.0, 0.0, 0.0, 0.0])
    assert np.array_equal(nm.safe_fmod(np.full(5, 5.5), z), [0.0, 1.5, 5.5, 1.5, 0.0])
    assert np.array_equal(nm.wrap(np.array([5.0, -0.25]), np.array([1.0, 1.0]), np.array([0.0, 1.0])), [0.0, 1.0])
    assert np.array_equal(nm.compatible_sign(np.array([-0.0, 3.0, -2.0])), [0.0, 1.0, -1.0])
    n = 2
    atan = nm.math_kernel({"Value": np.array([0.0, 0.0]), "Value_001": np.array([-0.0, -1.0]),
                           "Value_002": np.zeros(n)}, {"operation": "ARCTAN2"}, ctx(n))["Value"]
    assert np.allclose(atan, [0.0, np.pi])
    legacy = nm.math_kernel({"Value": np.array([0.0]), "Value_001": np.array([-0.0]), "Value_002": np.zeros(1)},
                            {"operation": "ARCTAN2"}, ctx(1, (3, 4)))["Value"]
    assert np.allclose(legacy, [np.pi])                  # 3.4: atan2f(0, -0)


def test_legacy_operations_and_clamp():
    n = 3
    v = {"Value": np.array([-1.0, 0.5, 2.0]), "Value_001": np.ones(n), "Value_002": np.zeros(n)}
    assert np.array_equal(nm.math_kernel(v, {"operation": "ADD", "use_clamp": True}, ctx(n))["Value"], [0.0, 1.0, 1.0])
    with pytest.raises(Exception):
        nm.math_kernel(v, {"operation": "FLOORED_MODULO"}, ctx(n, (3, 4)))
    vec = {"Vector": np.ones((3, n)), "Vector_001": np.ones((3, n)), "Vector_002": np.ones((3, n)), "Scale": np.ones(n)}
    with pytest.raises(Exception):
        nm.vector_math_kernel(vec, {"operation": "SIGN"}, ctx(n, (3, 4)))
    out = nm.vector_math_kernel(vec, {"operation": "DOT_PRODUCT"}, ctx(n))
    assert np.array_equal(out["Value"], [3.0, 3.0, 3.0]) and not out["Vector"].any()
    r = nm.clamp_kernel({"Value": np.array([0.5, 5.0]), "Min": np.array([1.0, 1.0]), "Max": np.array([0.0, 2.0])},
                        {"clamp_type": "RANGE"}, ctx(2))["Result"]
    assert np.array_equal(r, [0.5, 2.0])
