"""The node-program evaluator (engine/nodes/evaluator.py), the registry (engine/nodes/registry.py) and the
programs' scene data (engine/scene/programs.py): broadcasting, socket conversions, folding, files."""
import numpy as np
import pytest

from engine.core.errors import SceneError
from engine.nodes import registry
from engine.nodes.context import NodeContext, Varying
from engine.nodes.evaluator import LUMINANCE, UnsupportedNode, convert, fold, run
from engine.scene.programs import Link, Program, ProgramNode, program_json, read_program


def ctx_at(points, normals=None):
    points = np.asarray(points, dtype=np.float64)
    attrs = {"position": points, "normal": normals if normals is not None else np.tile([[0.0], [0.0], [1.0]], points.shape[1])}
    return NodeContext(points.shape[1], (5, 0), attrs)


def position_program(target="RGBA", scale=(2.0, 2.0, 2.0)):
    return Program([ProgramNode("ShaderNodeNewGeometry", "Geometry"),
                    ProgramNode("ShaderNodeMapping", "Mapping", {"vector_type": "POINT"},
                                {"Vector": Link(0, "Position", "VECTOR", "VECTOR"), "Scale": scale})],
                   (1, "Vector", "VECTOR"), target)


def test_registry_merges_the_kernel_modules_there_are():
    table = registry.kernels()
    assert {"ShaderNodeTexCoord", "ShaderNodeMapping", "ShaderNodeTexImage", "TNCG15Scale"} <= set(table)
    assert registry.supported("ShaderNodeMapping") and not registry.supported("ShaderNodeNoSuchNode")


def test_program_runs_per_point_and_converts_to_the_input_type():
    p = np.array([[0.0, 1.0, 2.0], [1.0, 2.0, 3.0], [0.5, 0.5, 0.5]])
    color = run(position_program("RGBA"), ctx_at(p))
    assert np.allclose(color, 2.0 * p)
    value = run(position_program("VALUE"), ctx_at(p))           # vector -> float: the average
    assert np.allclose(value, (2.0 * p).mean(axis=0))


def test_conversions_as_cycles():
    c = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    assert np.allclose(convert(c, "RGBA", "VALUE", 2), LUMINANCE[:2])
    assert np.allclose(convert(c, "VECTOR", "VALUE", 2), [1 / 3, 1 / 3])
    assert convert(np.array([0.25, 0.5]), "VALUE", "RGBA", 2).shape == (3, 2)


def test_constant_subgraph_folds_to_a_value():
    program = Program([ProgramNode("ShaderNodeValue", "Value", {"value": 0.3}),
                       ProgramNode("ShaderNodeMapping", "Mapping", {"vector_type": "POINT"},
                                   {"Vector": Link(0, "Value", "VALUE", "VECTOR"), "Scale": (2.0, 2.0, 2.0)})],
                      (1, "Vector", "VECTOR"), "VALUE")
    folded, value = fold(program)
    assert folded is None and value == pytest.approx(0.6)


def test_fold_keeps_the_varying_nodes_and_makes_constants_of_the_rest():
    program = Program([ProgramNode("ShaderNodeRGB", "RGB", {"color": (0.1, 0.2, 0.3)}),
                       ProgramNode("ShaderNodeNewGeometry", "Geometry"),
                       ProgramNode("ShaderNodeMapping", "Mapping", {"vector_type": "POINT"},
                                   {"Vector": Link(1, "Position", "VECTOR", "VECTOR"),
                                    "Location": Link(0, "Color", "RGBA", "VECTOR")})],
                      (2, "Vector", "VECTOR"), "RGBA")
    folded, value = fold(program)
    assert value is None and [n.kind for n in folded.nodes] == ["ShaderNodeNewGeometry", "ShaderNodeMapping"]
    assert folded.nodes[1].inputs["Location"] == pytest.approx((0.1, 0.2, 0.3))
    p = np.array([[1.0], [2.0], [3.0]])
    assert np.allclose(run(folded, ctx_at(p)), run(program, ctx_at(p)))


def test_a_hit_attribute_without_hits_is_varying():
    with pytest.raises(Varying):
        NodeContext(1).attr("position")


def test_unknown_node_type_is_named():
    program = Program([ProgramNode("ShaderNodeNoSuchNode", "X")], (0, "Color", "RGBA"))
    with pytest.raises(UnsupportedNode):
        run(program, NodeContext(2))


def test_programs_round_trip_through_scene_file_fields():
    program = position_program()
    again = read_program(program_json(program), "test")
    assert again == program
    again.validate("test")


def test_bad_program_is_refused():
    bad = Program([ProgramNode("ShaderNodeMapping", "Mapping", {}, {"Vector": Link(3, "Vector", "VECTOR", "VECTOR")})],
                  (0, "Vector", "VECTOR"))
    with pytest.raises(SceneError, match="not an earlier node"):
        bad.validate("Material 'M'")


def broadcast_cases(rng, n=200):
    """(program, ctx) pairs: Mapping of every vector type with constant Location / Rotation / Scale (zeros,
    -0.0, NaN (in a rotation angle too), inf, a zero scale for the divisions), and Scale (TNCG15Scale) of a colour and of a value."""
    p = rng.normal(size=(3, n)) * 3.0
    p[:, 0], p[0, 1], p[1, 2], p[:, 3] = np.nan, np.inf, -0.0, 0.0
    ctx = ctx_at(p, rng.normal(size=(3, n)))
    geometry = ProgramNode("ShaderNodeNewGeometry", "Geometry")
    cases = []
    for kind in ("POINT", "TEXTURE", "VECTOR", "NORMAL"):
        for loc, rot, scale in (((0.3, -0.0, 7.0), (0.1, 0.4363323152065277, -2.0), (2.0, 0.5, 3.0)),
                                ((np.nan, 0.0, 1.0), (0.0, 0.0, 0.0), (0.0, -1.5, np.inf)),
                                ((0.3, 0.2, -1.0), (0.3, 0.2, np.nan), (1.0, 2.0, 3.0)),
                                ((0.0, 0.0, 0.0), (np.nan, 0.3, 0.2), (-0.0, 1.0, 1.0))):
            mapping = ProgramNode("ShaderNodeMapping", "Mapping", {"vector_type": kind},
                                  {"Vector": Link(0, "Position", "VECTOR", "VECTOR"), "Location": loc,
                                   "Rotation": rot, "Scale": scale})
            cases.append((Program([geometry, mapping], (1, "Vector", "VECTOR"), "RGBA"), ctx))
    for source, output in (("RGBA", "Position"), ("VALUE", "Backfacing")):
        ctx_b = NodeContext(n, (5, 0), {"position": p, "backfacing": (rng.random(n) < 0.5).astype(np.float64)})
        scaled = ProgramNode("TNCG15Scale", "Scale", {}, {"Color": Link(0, output, "VECTOR" if source == "RGBA" else "VALUE",
                                                                        source), "Strength": 14.0})
        cases.append((Program([geometry, scaled], (1, "Color", "RGBA"), "RGBA"), ctx_b))
    return cases


def same_bits(a, b):
    return a.shape == b.shape and np.array_equal(a, b, equal_nan=True) and np.array_equal(np.signbit(a), np.signbit(b))


def test_constants_a_kernel_broadcasts_give_the_numbers_of_full_arrays(monkeypatch):
    """Mapping's and Scale's constants given as one value (registry.broadcast_inputs) give the outputs of
    the full arrays (the registry's list emptied) bit for bit, in shape; a control: a constant moved by
    one ulp is told apart; and Rotation, left out of the list, would not keep the bits (a NaN angle)."""
    assert registry.broadcast_inputs("ShaderNodeMapping") == ("Location", "Scale")
    rng = np.random.default_rng(11)
    with np.errstate(all="ignore"):
        one = [run(program, ctx) for program, ctx in broadcast_cases(rng)]
        registry.kernels()
        monkeypatch.setattr(registry, "_BROADCAST", {})
        assert registry.broadcast_inputs("ShaderNodeMapping") == ()
        full = [run(program, ctx) for program, ctx in broadcast_cases(np.random.default_rng(11))]
        assert all(same_bits(a, b) for a, b in zip(one, full))
        program, ctx = broadcast_cases(np.random.default_rng(11))[0]
        node = program.nodes[1]
        moved = dict(node.inputs, Scale=(np.nextafter(2.0, 3.0), 0.5, 3.0))
        program.nodes[1] = ProgramNode(node.kind, node.name, node.props, moved)
        assert not same_bits(run(program, ctx), full[0])
        monkeypatch.setattr(registry, "_BROADCAST", {"ShaderNodeMapping": ("Location", "Rotation", "Scale")})
        rotated = [run(program, ctx) for program, ctx in broadcast_cases(np.random.default_rng(11))]
        assert not all(same_bits(a, b) for a, b in zip(rotated, full))
