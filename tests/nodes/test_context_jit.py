"""The compiled Object and Generated attributes (engine/nodes/context_jit.py) against engine/nodes/context.py's
NumPy ones, bit for bit: on the contexts of the node programs of a real render (two transformed meshes, one
with its texture space given and one with Blender's automatic one, a sphere among the triangle hits, a lamp
whose emission is a program of Generated read at light samples too; NumPy backend, the contexts' arrays as the
render gave them, layouts kept) and on hand-made points (both layouts, one matrix and one per point, NaN,
+-inf, -0.0, zeros, no points).  Controls: the other summation order and a reciprocal multiplication for
the division give other bits on these inputs, and the comparison sees a one-ulp change of a point."""
import numpy as np
import pytest

from engine import api
from engine.core.settings import RenderSettings
from engine.geometry.scene_geometry import TRIANGLE
from engine.nodes import context
from engine.nodes.context import HitPoints, SceneAttributes
from engine.scene.model import Camera, Material, Scene, Sphere, TriangleMesh
from engine.scene.programs import Link, Program, ProgramNode
from tests.backend_capture import require_compiled


def coordinates(output, kind):
    """A program giving Texture Coordinate's `output` as a value of socket type `kind`."""
    node = ProgramNode("ShaderNodeTexCoord", "Coords", {"_outputs": [output]})
    return Program([node], (0, output, "VECTOR"), kind)


def quad(name, matrix, material, texspace=None):
    """A unit square (two triangles) in object space, placed by `matrix`."""
    local = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    world = local @ matrix[:3, :3].T + matrix[:3, 3]
    return TriangleMesh(name, world, np.array([[0, 1, 2], [0, 2, 3]]), np.full(2, material),
                        object_matrix=matrix, texspace=texspace)


def placed(axis, angle, scale, location):
    """An object matrix (4, 4): a rotation by `angle` about `axis` (Rodrigues), then scaled, then moved
    (every entry of the inverse non-zero: each term of the object-space sums counts)."""
    k = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    m = np.eye(4)
    m[:3, :3] = (np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * cross @ cross) @ np.diag(scale)
    m[:3, 3] = location
    return m


def scene():
    """A floor and a wall (moved, turned, scaled; texture spaces given and Blender's automatic one), a sphere,
    a lamp: colours of Object, roughness of Generated, the lamp's emission of Generated."""
    floor = placed((0.1, 0.2, 1.0), 0.4, (2.1, 1.7, 1.3), (0.3, -0.2, 0.05))
    wall = placed((1.0, 0.15, 0.1), 1.5, (1.6, 1.3, 1.1), (0.1, 1.5, 1.2))
    lamp = placed((1.0, 0.05, 0.0), np.pi, (0.45, 0.35, 1.0), (0.0, 0.2, 2.4))
    painted = Material("Painted", "principled", (0.8, 0.8, 0.8), roughness=0.4,
                       programs={"color": coordinates("Object", "RGBA"), "roughness": coordinates("Generated", "VALUE")})
    glowing = Material("Lamp", "diffuse", (0.0, 0.0, 0.0), emission=(5.0, 5.0, 5.0),
                       programs={"emission": coordinates("Generated", "RGBA")})
    meshes = [quad("Floor", floor, 0, ((0.1, -0.3, 0.07), (0.7, 1.3, 0.3))), quad("Wall", wall, 0),
              quad("Lamp", lamp, 1, ((0.02, 0.0, 0.0), (0.9, 1.1, 0.6)))]
    camera = Camera.look_at((0.0, -4.0, 1.5), (0.0, 0.5, 0.6), lens=30)
    return Scene(camera, [painted, glowing], meshes, [Sphere("Ball", (0.4, 0.2, 0.4), 0.35, 0)], [],
                 background=(0.05, 0.05, 0.05), resolution=(24, 24))


def captured_calls():
    """[(SceneAttributes, args of its context())] of a 24 x 24, 8 spp NumPy render of scene(): every
    program's hits (at bounces and light samples), their arrays copied as they are laid out."""
    calls, original = [], SceneAttributes.context

    def copied(a):
        return a if a is None or not isinstance(a, np.ndarray) else np.array(a, order="K")

    def recording(self, kind, prim, b1, b2, points, *rest):
        kept = None if points is None else HitPoints(**{f: copied(getattr(points, f)) for f in HitPoints.FIELDS})
        calls.append((self, (copied(kind), copied(prim), copied(b1), copied(b2), kept) + rest))
        return original(self, kind, prim, b1, b2, points, *rest)
    SceneAttributes.context = recording
    try:
        api.render(scene(), RenderSettings(samples=8, threads=1, backend="numpy", max_depth=4), log=lambda m: None)
    finally:
        SceneAttributes.context = original
    return calls


def same(a, b):
    return a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True) and np.array_equal(np.signbit(a), np.signbit(b))


@pytest.fixture(scope="module")
def calls():
    return captured_calls()


def test_the_attributes_of_a_render_are_the_numpy_numbers(calls):
    require_compiled()
    from engine.nodes import context_jit
    assert len(calls) >= 10
    sizes, layouts, partial = 0, set(), 0
    for attrs, args in calls:
        kind, points = args[0], args[4]
        sizes += len(kind)
        partial += int((kind != TRIANGLE).any() and (kind == TRIANGLE).any())
        if points is not None and points.point is not None:
            layouts.add(context.components_adjacent(points.point))
        reference = attrs.context(*args)
        expected = {name: reference.attr(name) for name in ("object", "generated")}    # read before the switch
        attrs.compiled = context_jit
        try:
            compiled = attrs.context(*args)
            for name, values in expected.items():
                assert same(values, compiled.attr(name)), name
        finally:
            attrs.compiled = None
    # Thousands of points, contexts with sphere hits among the triangles', the wavefront's rows (the
    # other layout: test_hand_made_points_are_the_numpy_numbers).
    assert sizes > 1000 and partial > 0 and False in layouts


def hand_made(rng, k, adjacent):
    points = rng.normal(size=(k, 3)).T if adjacent else rng.normal(size=(3, k))
    points = np.array(points, order="F" if adjacent else "C")
    if k >= 8:
        points[:, 0], points[0, 1], points[1, 2], points[2, 3] = np.nan, np.inf, -np.inf, -0.0
        points[:, 4] = 0.0
        points[:, 5] = -0.0
    return points


@pytest.mark.parametrize("adjacent", [False, True])
@pytest.mark.parametrize("k", [0, 1, 9, 300])
@pytest.mark.parametrize("per_point", [False, True])
def test_hand_made_points_are_the_numpy_numbers(adjacent, k, per_point):
    require_compiled()
    from engine.nodes import context_jit
    rng = np.random.default_rng(k + 2 * adjacent)
    points = hand_made(rng, k, adjacent)
    if k > 1:
        assert context.components_adjacent(points) is adjacent
    m = rng.normal(size=(k if per_point else 1, 3, 4))
    if len(m) > 6:
        m[6] = 0.0                                          # all-zero terms: -0.0 * x sums
        m[7, 0, 3] = np.nan
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        reference = context.object_points(m, points)
        compiled = context_jit.object_points(m, points, context.components_adjacent(points) or False)
        assert same(reference, compiled) and compiled.flags.c_contiguous
        centre, size = rng.normal(size=(len(m), 3)), rng.random((len(m), 3))
        if len(m) > 6:
            size[6] = 0.0                                   # a flat side: +-inf, NaN
        expected = (reference - centre.T) / (2.0 * size.T) + 0.5
        assert same(expected, context_jit.generated(reference, centre, size))


def test_refuses_other_numbers_of_matrices():
    require_compiled()
    from engine.nodes import context_jit
    with pytest.raises(ValueError):
        context_jit.object_points(np.zeros((2, 3, 4)), np.zeros((3, 3)), False)


def test_controls_other_operations_give_other_bits():
    """The other summation order, a multiplication by the reciprocal for the division and a point moved by
    one ulp each change some of the numbers, and the comparison says so."""
    require_compiled()
    from engine.nodes import context_jit
    rng = np.random.default_rng(5)
    points, m = rng.normal(size=(3, 500)) * 7.0, rng.normal(size=(1, 3, 4))
    reference = context.object_points(m, points)
    assert not same(reference, context_jit.object_points(m, np.asfortranarray(points), True))   # (0 + 2) + 1
    moved = points.copy()
    moved[1, 17] = np.nextafter(moved[1, 17], np.inf)
    assert not same(reference, context_jit.object_points(m, moved, False))
    centre, size = rng.normal(size=(1, 3)), rng.random((1, 3)) * 3.0
    assert not same((reference - centre.T) * (1.0 / (2.0 * size.T)) + 0.5,
                    context_jit.generated(reference, centre, size))


def test_refuses_other_numbers_of_centres_and_sizes():
    """Generated's twin reads centre and size rows 0 (one object) or 0..k-1 (one per point): other counts
    or widths are refused, not read out of range."""
    require_compiled()
    from engine.nodes import context_jit
    o = np.zeros((3, 5))
    for centre, size in ((np.zeros((2, 3)), np.ones((2, 3))), (np.zeros((1, 3)), np.ones((5, 3))),
                         (np.zeros((1, 2)), np.ones((1, 2)))):
        with pytest.raises(ValueError):
            context_jit.generated(o, centre, size)
    assert context_jit.generated(o, np.zeros((5, 3)), np.ones((5, 3))).shape == (3, 5)      # the control
