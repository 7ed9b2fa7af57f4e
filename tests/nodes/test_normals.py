"""Normal Map and Bump (engine/nodes/normals.py) against hand-computed normals, and the machinery they
need: the mesh's tangents and bitangent signs at hits, the shifted contexts of Bump's heights
(engine/nodes/context.py SceneAttributes), the evaluator's offset inputs, Cycles' valid-reflection
correction and bump shadowing term.  The Cycles renders: tests/nodes/test_agreement_normals.py."""
import numpy as np
import pytest

from engine.geometry.scene_geometry import TRIANGLE
from engine.nodes import normals
from engine.nodes.context import HitPoints, NodeContext, SceneAttributes
from engine.nodes.evaluator import run
from engine.scene.model import Material, Scene, TriangleMesh
from engine.scene.programs import Link, Program, ProgramNode

X, Y, Z = (np.array([[1.0], [0.0], [0.0]]), np.array([[0.0], [1.0], [0.0]]), np.array([[0.0], [0.0], [1.0]]))


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return (v / np.linalg.norm(v))[:, None]


@pytest.mark.parametrize("version", [(3, 4), (5, 0)])
def test_tangent_space_normal_is_t_b_n_of_the_colour(version):
    """Colour (0.75, 0.25, 1) is 2c - 1 = (0.5, -0.5, 1): +x along the tangent, -y along B =
    sign cross(n, t).  With t = x, n = z, sign +1: B = +y."""
    c = np.array([[0.75], [0.25], [1.0]])
    n = normals.tangent_space_normal(c, X, np.ones(1), Z, np.zeros(1, bool), np.ones(1), version)
    assert np.allclose(n, unit([0.5, -0.5, 1.0]))
    flipped_sign = normals.tangent_space_normal(c, X, -np.ones(1), Z, np.zeros(1, bool), np.ones(1), version)
    assert np.allclose(flipped_sign, unit([0.5, 0.5, 1.0]))               # CONTROL: the sign matters
    flipped_tangent = normals.tangent_space_normal(c, -X, np.ones(1), Z, np.zeros(1, bool), np.ones(1), version)
    assert not np.allclose(flipped_tangent, n)
    back = normals.tangent_space_normal(c, X, np.ones(1), Z, np.ones(1, bool), np.ones(1), version)
    assert np.allclose(back, -n)                                          # back faces: flipped


def test_tangent_space_strength_in_5_0_scales_xy_and_mixes_z():
    c = np.array([[1.0], [0.5], [0.0]])                   # 2c - 1 = (1, 0, -1)
    n = normals.tangent_space_normal(c, X, np.ones(1), Z, np.zeros(1, bool), np.full(1, 0.5), (5, 0))
    assert np.allclose(n, unit([0.5, 0.0, 0.0]))          # z: mix(1, -1, 0.5) = 0


def context(n, normal, **attributes):
    base = {"normal": normal, "backfacing": np.zeros(n), "true_normal": normal, "incoming": normal,
            "tangent_base": normal}
    base.update(attributes)
    return NodeContext(n, (5, 0), base)


def test_normal_map_kernel_spaces():
    ctx = context(1, Z, tangent=X, tangent_sign=np.ones(1), has_tangent=np.ones(1, bool),
                  object_to_world_normal=lambda c: c / np.linalg.norm(c, axis=0))
    colour = np.array([[0.75], [0.25], [1.0]])
    tangent = normals.normal_map({"Color": colour, "Strength": np.ones(1)}, {"space": "TANGENT"}, ctx)["Normal"]
    assert np.allclose(tangent, unit([0.5, -0.5, 1.0]))
    world = normals.normal_map({"Color": colour, "Strength": np.ones(1)}, {"space": "WORLD"}, ctx)["Normal"]
    assert np.allclose(world, unit([0.5, -0.5, 1.0]))
    blender = normals.normal_map({"Color": colour, "Strength": np.ones(1)}, {"space": "BLENDER_WORLD"}, ctx)["Normal"]
    assert np.allclose(blender, unit([0.5, 0.5, -1.0]))
    none = context(1, Z, tangent=np.zeros((3, 1)), tangent_sign=np.zeros(1), has_tangent=np.zeros(1, bool))
    assert np.allclose(normals.normal_map({"Color": colour, "Strength": np.ones(1)}, {"space": "TANGENT"}, none)["Normal"], Z)


def tilted_scene():
    """One triangle in the plane z = 0 (UVs = x, y), its object the identity."""
    verts = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]])
    mesh = TriangleMesh("Tri", verts, np.array([[0, 1, 2]]), np.array([0]),
                        uvs=np.array([[[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]]]),
                        tangents=np.tile(np.array([1.0, 0.0, 0.0]), (1, 3, 1)), tangent_signs=np.array([[-1.0] * 3]),
                        object_matrix=np.eye(4))
    return Scene(None, [Material("M")], [mesh], [], [])


def hit_context(scene, version=(5, 0)):
    attrs = SceneAttributes(scene, scene.meshes[0].vertices[scene.meshes[0].triangles],
                            np.array([[0.0], [0.0], [4.0], [0.0], [0.0], [4.0]]))
    b1, b2 = np.array([0.25]), np.array([0.25])                      # the point (1, 1, 0)
    points = HitPoints(point=np.array([[1.0], [1.0], [0.0]]), direction=-Z.copy(), normal=Z, shading=Z,
                       distance=np.full(1, 3.0))
    return attrs.context(np.array([TRIANGLE]), np.array([0]), b1, b2, points, version, None, TRIANGLE)


def test_mesh_tangents_and_signs_reach_the_normal_map():
    ctx = hit_context(tilted_scene())
    assert np.allclose(ctx.attr("tangent"), X) and ctx.attr("tangent_sign")[0] == -1.0
    colour = np.array([[0.5], [0.75], [1.0]])                        # +y in tangent space: -y here (sign -1)
    n = normals.normal_map({"Color": colour, "Strength": np.ones(1)}, {"space": "TANGENT"}, ctx)["Normal"]
    assert np.allclose(n, unit([0.0, -0.5, 1.0]))


def test_shifted_context_moves_position_and_uv_not_the_normal():
    ctx = hit_context(tilted_scene())
    moved = ctx.shifted(np.array([[0.5], [0.25], [0.0]]))
    assert np.allclose(moved.attr("position"), [[1.5], [1.25], [0.0]])
    assert np.allclose(moved.attr("uv"), [[1.5], [1.25], [0.0]])
    assert np.allclose(moved.attr("normal"), Z)


def height_program(slope, invert=False, distance=0.5):
    """Height = slope . Object position (Texture Coordinate -> Vector Math Dot Product) into a Bump."""
    nodes = [ProgramNode("ShaderNodeTexCoord", "coords", {"_outputs": ["Object"]}, {}),
             ProgramNode("ShaderNodeVectorMath", "dot", {"operation": "DOT_PRODUCT", "_outputs": ["Value"]},
                         {"Vector": Link(0, "Object", "VECTOR", "VECTOR"), "Vector_001": tuple(slope)}),
             ProgramNode("ShaderNodeBump", "bump", {"invert": invert, "_outputs": ["Normal"]},
                         {"Height": Link(1, "Value", "VALUE", "VALUE"), "Strength": 1.0, "Distance": distance,
                          "Filter Width": 0.1})]
    return Program(nodes, (2, "Normal", "VECTOR"), "VECTOR")


@pytest.mark.parametrize("version", [(3, 4), (5, 0)])
def test_bump_of_a_linear_height_is_n_minus_distance_times_the_surface_gradient(version):
    slope = (0.6, -0.4, 2.0)                          # the z part is along N: no effect
    n = run(height_program(slope), hit_context(tilted_scene(), version))
    assert np.allclose(n, unit([-0.3, 0.2, 1.0]), atol=1e-6)
    inverted = run(height_program(slope, invert=True), hit_context(tilted_scene(), version))
    assert np.allclose(inverted, unit([0.3, -0.2, 1.0]), atol=1e-6)     # CONTROL: Invert flips the tilt


def test_bump_without_a_linked_height_keeps_the_normal():
    program = height_program((1.0, 0.0, 0.0))
    program.nodes[2].inputs["Height"] = 0.3
    assert np.allclose(run(program, hit_context(tilted_scene())), Z)


@pytest.mark.parametrize("version", [(3, 4), (5, 0)])
def test_valid_reflection_lifts_normals_whose_reflection_goes_below(version):
    ng = np.repeat(Z, 3, axis=1)
    incoming = np.repeat(unit([1.0, 0.0, 0.3]), 3, axis=1)
    n = np.concatenate([Z, unit([-1.0, 0.0, 0.4]), unit([-1.0, 0.0, 1.0])], axis=1)
    out = normals.ensure_valid_reflection(ng, incoming, n, version)
    assert np.allclose(out[:, 0], Z[:, 0])                           # valid: kept
    r = 2.0 * (out * incoming).sum(0) * out - incoming
    assert np.all(r[2] >= np.minimum(0.9 * incoming[2], 0.01) - 1e-6)
    assert np.allclose(np.linalg.norm(out, axis=0), 1.0)


@pytest.mark.parametrize("version", [(3, 4), (5, 0)])
def test_bump_shadowing_is_one_for_the_smooth_normal_and_dims_grazing_light(version):
    smooth = np.repeat(Z, 2, axis=1)
    tilted = np.repeat(unit([0.6, 0.0, 0.8]), 2, axis=1)
    wi = np.concatenate([unit([0.0, 0.0, 1.0]), unit([1.0, 0.0, 0.05])], axis=1)
    diffuse = np.ones(2, bool)
    assert np.all(normals.bump_shadowing(smooth, smooth, wi, diffuse, True, version) == 1.0)
    term = normals.bump_shadowing(smooth, tilted, wi, diffuse, True, version)
    assert term[0] == pytest.approx(1.0) and 0.0 <= term[1] < 0.9


def test_two_object_space_normal_maps_in_one_program():
    """Two Object-space Normal Map nodes, the second fed by the first, on one context: the context's
    object_to_world_normal (an attribute that is a function) read twice.  (It was made by a lazy entry
    and then stored in its place, so the second read called the function itself without its argument:
    TypeError; found by review.)  The chain equals the second node fed the first's output as a constant."""
    from engine.geometry.scene_geometry import TRIANGLE
    from engine.nodes.context import SceneAttributes
    from engine.nodes.evaluator import run
    from engine.scene.model import Material, Scene, TriangleMesh
    from engine.scene.programs import Link, Program, ProgramNode

    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.]])
    tris = np.array([[0, 1, 2]])
    matrix = np.eye(4)
    matrix[:3, :3] = [[0.0, -2.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]     # turned, stretched: not the identity
    mesh = TriangleMesh("A", verts, tris, np.zeros(1, np.int64), object_matrix=matrix)
    attrs = SceneAttributes(Scene(None, [Material("M")], [mesh], [], []), verts[tris], None)

    def context():
        n = 4
        return attrs.context(np.full(n, TRIANGLE, np.int8), np.zeros(n, np.int64), np.full(n, .2),
                             np.full(n, .3), None, (5, 0), None, TRIANGLE)

    def node(name, color):
        return ProgramNode("ShaderNodeNormalMap", name, {"space": "OBJECT", "_outputs": ["Normal"]},
                           {"Color": color, "Strength": 1.0})

    color = (0.7, 0.5, 0.9)
    one = run(Program([node("a", color)], (0, "Normal", "VECTOR"), "VECTOR"), context())
    chain = run(Program([node("a", color), node("b", Link(0, "Normal", "VECTOR", "RGBA"))],
                        (1, "Normal", "VECTOR"), "VECTOR"), context())
    first = np.asarray(one).reshape(3, -1)[:, 0]                  # the same at every hit
    second = run(Program([node("b", tuple(float(c) for c in first))], (0, "Normal", "VECTOR"), "VECTOR"),
                 context())
    assert np.all(np.isfinite(np.asarray(chain)))
    assert np.array_equal(np.asarray(chain), np.asarray(second))
    assert not np.allclose(np.asarray(chain), np.asarray(one))     # the second node did turn it
