"""The compiled Normal Map node in tangent space (engine/nodes/normals_jit.py tangent_normal_map) against
engine/nodes/normals.py's NumPy normal_map, bit for bit: on the node's calls in real renders (a
smooth-shaded, UV-mapped and tangent-carrying ground whose Principled BSDF's Normal is a Normal Map of the
UV coordinates, under a sun, Blender 3.4's and 5.0's rules) and on hand-made inputs (strengths below 0,
0, between, 1, above 1 and NaN; back faces; hits without tangents; colours and tangents with NaN, inf
and -0.0; zero tangents; a constant colour (3,)); a control shows the comparison sees a last-bit change.
normal_map runs the twin within engine/geometry/shading_normals.py compiled_for(True) (a numba render)."""
import numpy as np
import pytest

from engine import api
from engine.core.settings import RenderSettings
from engine.geometry.shading_normals import compiled_for
from engine.nodes import normals
from engine.nodes.context import NodeContext
from engine.nodes.registry import kernels
from engine.scene.model import Camera, Material, Scene, SunLight, TriangleMesh
from engine.scene.programs import Link, Program, ProgramNode
from tests.backend_capture import require_compiled


def ground(version):
    """A 4 x 4 ground of 32 triangles, smooth (wavy corner normals), UVs and tangents (signs of both
    kinds), its Principled BSDF's Normal a Normal Map (strength 0.7) of the UV coordinates."""
    rng = np.random.default_rng(4)
    x, y = np.meshgrid(np.linspace(-2.0, 2.0, 5), np.linspace(-2.0, 2.0, 5))
    verts = np.stack([x.ravel(), y.ravel(), 0.1 * rng.normal(size=25)], axis=1)
    quads = [(5 * r + c, 5 * r + c + 1, 5 * r + c + 6, 5 * r + c + 5) for r in range(4) for c in range(4)]
    tris = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    normals_ = np.tile([0.0, 0.0, 1.0], (len(tris), 3, 1)) + 0.3 * rng.normal(size=(len(tris), 3, 3))
    normals_ /= np.linalg.norm(normals_, axis=2)[:, :, None]
    uvs = verts[tris][:, :, :2] / 4.0 + 0.5
    tangents = np.tile([1.0, 0.0, 0.0], (len(tris), 3, 1)) + 0.2 * rng.normal(size=(len(tris), 3, 3))
    signs = np.where(np.arange(len(tris)) % 3 == 0, -1.0, 1.0)[:, None].repeat(3, axis=1)
    mesh = TriangleMesh("Ground", verts, tris, np.zeros(len(tris), np.int64), uvs=uvs, tangents=tangents,
                        tangent_signs=signs, object_matrix=np.eye(4))
    mesh.normals = normals_
    program = Program([ProgramNode("ShaderNodeTexCoord", "coords", {"_outputs": ["UV"]}, {}),
                       ProgramNode("ShaderNodeNormalMap", "map", {"space": "TANGENT", "_outputs": ["Normal"]},
                                   {"Color": Link(0, "UV", "VECTOR", "RGBA"), "Strength": 0.7})],
                      (1, "Normal", "VECTOR"), "VECTOR")
    material = Material("Mapped", "principled", (0.8, 0.8, 0.8), roughness=0.3, programs={"normal": program})
    camera = Camera.look_at((0.0, -4.0, 3.0), (0.0, 0.0, 0.0), lens=35)
    scene = Scene(camera, [material], [mesh], [], [], resolution=(16, 16))
    scene.suns = [SunLight("Sun", (0.3, 0.4, -1.0), (3.0, 3.0, 3.0), angle=0.1)]
    scene.background = (0.1, 0.1, 0.1)
    scene.cycles_version = version
    return scene


def capture(version, limit=6):
    """[(inputs, props, ctx)] of normal_map's calls in a 16 x 16, 2 spp NumPy render of ground(version),
    the context's attributes read at once (they are computed on first use)."""
    calls = []

    def record(inputs, props, ctx):
        if len(calls) < limit:
            names = ("normal", "backfacing", "tangent", "tangent_sign", "has_tangent", "tangent_base")
            kept = NodeContext(ctx.n, ctx.cycles_version, {k: np.array(ctx.attr(k)) for k in names})
            calls.append(({k: np.array(v) for k, v in inputs.items()}, dict(props), kept))
    render_seeing(ground(version), record)
    return calls


def render_seeing(scene, record):
    """A 2 spp NumPy render of `scene` in which record(inputs, props, ctx) sees each Normal Map call first."""
    original = normals.normal_map

    def recording(inputs, props, ctx):
        record(inputs, props, ctx)
        return original(inputs, props, ctx)
    table = kernels()                         # the evaluator's table of kernels, built once
    table["ShaderNodeNormalMap"] = recording
    try:
        api.render(scene, RenderSettings(samples=2, threads=1, backend="numpy"), log=lambda m: None)
    finally:
        table["ShaderNodeNormalMap"] = original


def both(inputs, props, ctx):
    """(NumPy's Normal, the compiled one) of normal_map(inputs, props, ctx)."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        reference = normals.normal_map(inputs, props, ctx)["Normal"]
        with compiled_for(True):
            compiled = normals.normal_map(inputs, props, ctx)["Normal"]
    return reference, compiled


def same(a, b):
    return a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True) and np.array_equal(np.signbit(a), np.signbit(b))


@pytest.mark.parametrize("version", [(3, 4), (5, 0)])
def test_recorded_calls_are_the_numpy_numbers(version):
    require_compiled()
    calls = capture(version)
    assert len(calls) >= 2 and sum(ctx.n for _, _, ctx in calls) > 100
    for inputs, props, ctx in calls:
        assert same(*both(inputs, props, ctx))


def hand_made(version, m=400, seed=9):
    rng = np.random.default_rng(seed)
    normal = rng.normal(size=(3, m))
    normal /= np.linalg.norm(normal, axis=0)
    tangent = rng.normal(size=(3, m))
    base = normal + 0.1 * rng.normal(size=(3, m))
    colour = rng.random((3, m))
    strength = rng.choice([-0.5, -0.0, 0.0, 0.3, 1.0, 1.0, 1.6], m)
    strength[:4] = np.nan
    sign = rng.choice([-1.0, 1.0], m)
    has = rng.random(m) < 0.85
    back = (rng.random(m) < 0.3).astype(np.float64)
    colour[:, 10], colour[0, 11], colour[1, 12], colour[:, 13] = np.nan, np.inf, -np.inf, 0.5   # 0.5: (0, 0, 0)
    tangent[:, 14], base[:, 15], tangent[2, 16], base[0, 17] = 0.0, 0.0, -0.0, np.nan
    normal[:, 18] = np.nan
    ctx = NodeContext(m, version, {"normal": normal, "backfacing": back, "tangent": tangent, "tangent_sign": sign,
                                   "has_tangent": has, "tangent_base": base})
    return {"Color": colour, "Strength": strength}, {"space": "TANGENT"}, ctx


@pytest.mark.parametrize("version", [(3, 4), (4, 2), (5, 0)])
def test_hand_made_inputs_are_the_numpy_numbers(version):
    require_compiled()
    inputs, props, ctx = hand_made(version)
    assert same(*both(inputs, props, ctx))
    constant = {"Color": np.array([0.6, 0.4, 0.9])}                    # a constant colour, strength 1
    assert same(*both(constant, props, ctx))


def test_control_a_last_bit_change_is_seen():
    """The colours moved by one ulp change the normals in their last bits, and the comparison says so."""
    require_compiled()
    inputs, props, ctx = hand_made((5, 0))
    reference, _ = both(inputs, props, ctx)
    inputs["Color"] = np.nextafter(inputs["Color"], 10.0)
    _, moved = both(inputs, props, ctx)
    assert np.allclose(moved, reference, atol=1e-12, equal_nan=True) and not same(moved, reference)


# -- at a scene's hits: the tangent frame interpolated in the kernel (normals_jit.corner_normal_map) --------
def capture_scene_calls(version, limit=6):
    """[(NumPy's Normal, the compiled one)] of normal_map's calls in a 16 x 16, 2 spp NumPy render of
    ground(version), both made on the render's own context at the call (SceneAttributes.context: the
    compiled one reads its tangent_corners)."""
    pairs = []

    def record(inputs, props, ctx):
        assert ctx.has("tangent_corners")
        if len(pairs) < limit:
            pairs.append(both(inputs, props, ctx))
    render_seeing(ground(version), record)
    return pairs


@pytest.mark.parametrize("version", [(3, 4), (5, 0)])
def test_recorded_scene_calls_interpolate_the_numpy_tangents(version):
    require_compiled()
    pairs = capture_scene_calls(version)
    assert len(pairs) >= 2 and sum(r.shape[1] for r, _ in pairs) > 100
    for reference, compiled in pairs:
        assert same(reference, compiled)


def corner_scene(tangents=True):
    """Six triangles whose corner tangents and signs hold the edge values: NaN, +-inf, -0.0, zero
    tangents, sign 0 and NaN; without `tangents` no mesh has any."""
    rng = np.random.default_rng(12)
    verts = rng.normal(size=(18, 3))
    tris = np.arange(18).reshape(6, 3)
    t = rng.normal(size=(6, 3, 3))
    s = rng.choice([-1.0, 1.0], (6, 3))
    t[1, 0, 0], t[1, 2, 1], t[2, 1] = np.nan, np.inf, 0.0
    t[3] = 0.0
    t[4, 0, 2], s[4, 1] = -np.inf, -0.0
    s[2] = 0.0
    s[5, 2] = np.nan
    mesh = TriangleMesh("Edges", verts, tris, np.zeros(6, np.int64), object_matrix=np.eye(4),
                        tangents=t if tangents else None, tangent_signs=s if tangents else None)
    return Scene(None, [Material("M")], [mesh], [], [])


def corner_context(scene, version, m=300, seed=5):
    """A context of m hits on corner_scene: triangles and other kinds (spheres, none), barycentrics
    inside, outside, 0, 1 and NaN, viewers on both sides (a shading normal given or not)."""
    from engine.geometry.scene_geometry import SPHERE, TRIANGLE
    from engine.nodes.context import HitPoints, SceneAttributes
    rng = np.random.default_rng(seed)
    attrs = SceneAttributes(scene, scene.meshes[0].vertices[scene.meshes[0].triangles], None)
    kind = rng.choice(np.array([TRIANGLE, TRIANGLE, TRIANGLE, SPHERE, 0], np.int8), m)
    prim = rng.integers(0, 6, m)
    b1, b2 = rng.random(m), rng.random(m) * 0.5
    if m >= 6:
        b1[:6], b2[:6] = [0.0, 1.0, -0.25, 1.5, np.nan, 0.0], [0.0, 0.0, 0.5, 0.1, 0.2, np.nan]
        kind[:6], prim[:6] = TRIANGLE, [0, 1, 2, 3, 4, 5]
    normal = rng.normal(size=(3, m))
    shading = normal + 0.2 * rng.normal(size=(3, m))
    points = HitPoints(direction=rng.normal(size=(3, m)), normal=normal, shading=shading)
    return attrs.context(kind, prim, b1, b2, points, version, None, TRIANGLE)


@pytest.mark.parametrize("version", [(3, 4), (5, 0)])
@pytest.mark.parametrize("tangents", [True, False])
def test_hand_made_scene_hits_are_the_numpy_numbers(version, tangents):
    require_compiled()
    inputs, props, _ = hand_made(version, m=300)
    ctx = corner_context(corner_scene(tangents), version)
    assert ctx.has("tangent_corners") and (ctx.attr("backfacing") > 0).any() and (ctx.attr("backfacing") == 0).any()
    assert same(*both(inputs, props, corner_context(corner_scene(tangents), version)))
    constant = {"Color": np.array([0.6, 0.4, 0.9])}
    assert same(*both(constant, props, corner_context(corner_scene(tangents), version)))
    empty = corner_context(corner_scene(tangents), version, m=0)
    assert same(*both({"Color": np.zeros((3, 0)), "Strength": np.zeros(0)}, props, empty))


def test_control_a_last_bit_change_of_a_corner_is_seen():
    """A corner tangent moved by one ulp changes the interpolated normals in their last bits, and the
    comparison says so (the kernel reads the corners, not the NumPy attributes)."""
    require_compiled()
    inputs, props, _ = hand_made((5, 0), m=300)
    scene = corner_scene()
    reference, _ = both(inputs, props, corner_context(scene, (5, 0)))
    scene.meshes[0].tangents[0, 1] = np.nextafter(scene.meshes[0].tangents[0, 1], 10.0)
    _, moved = both(inputs, props, corner_context(scene, (5, 0)))
    assert np.allclose(moved, reference, atol=1e-12, equal_nan=True) and not same(moved, reference)


def test_inputs_of_other_lengths_are_refused():
    """(3, 1) rows where N hits are meant would be read past their end by the loops: refused."""
    require_compiled()
    from engine.nodes import normals_jit
    from engine.nodes.context import TangentCorners
    rows, one = np.ones((3, 4)), np.ones((3, 1))
    with pytest.raises(ValueError, match="bump_shadowing"):
        normals_jit.bump_shadowing(one, rows, None, rows, rows, True, True)
    with pytest.raises(ValueError, match="bump_shadowing"):
        normals_jit.bump_shadowing(rows, rows, rows, rows, np.ones((3, 8)), True, True, repeat=3)
    assert normals_jit.bump_shadowing(rows, rows, rows, rows, np.ones((3, 8)), True, True, repeat=2).shape == (8,)
    corners = TangentCorners(np.ones(1, np.int8), np.zeros(1, np.int64), np.zeros(1), np.zeros(1), 1, None, None)
    with pytest.raises(ValueError, match="corner_normal_map"):
        normals_jit.corner_normal_map(rows, np.ones(4), corners, rows, np.ones(4), (5, 0))


def test_one_colour_and_strength_are_broadcast_to_the_hits():
    """The Normal Map's colour (3, 1) and strength (1,) stand for every hit (copied to N): the same normals
    as the full arrays, on both kernels."""
    require_compiled()
    from engine.nodes import normals_jit
    inputs, _, ctx = hand_made((5, 0), m=50)
    colour, strength = inputs["Color"][:, 7:8], inputs["Strength"][20:21]
    full = np.repeat(colour, 50, axis=1), np.repeat(strength, 50)
    names = ("tangent", "tangent_sign", "tangent_base")
    args = [ctx.attr(k) for k in names] + [ctx.attr("backfacing") > 0.5, ctx.attr("has_tangent"), ctx.attr("normal")]
    assert same(normals_jit.tangent_normal_map(colour, strength, *args, (5, 0)),
                normals_jit.tangent_normal_map(*full, *args, (5, 0)))
    scene_ctx = corner_context(corner_scene(), (5, 0), m=50)
    corners, shading, towards = scene_ctx.attr("tangent_corners"), scene_ctx.attr("normal"), scene_ctx.attr("_towards")
    assert same(normals_jit.corner_normal_map(colour, strength, corners, shading, towards, (5, 0)),
                normals_jit.corner_normal_map(*full, corners, shading, towards, (5, 0)))


def test_a_triangle_hit_outside_the_tangents_is_refused_on_both_backends():
    """A triangle hit whose primitive is past the scene's triangles: NumPy's take raises IndexError, and
    so does the compiled corner kernel (it read past the tangents' end before; found by review); the
    hits inside give the same normals on both."""
    require_compiled()
    from engine.geometry.scene_geometry import TRIANGLE
    from engine.geometry.shading_normals import compiled_for
    from engine.nodes import normals
    from engine.nodes.context import HitPoints, SceneAttributes
    from engine.scene.model import Material, Scene, TriangleMesh
    r = np.random.default_rng(1)
    mesh = TriangleMesh("A", r.normal(size=(6, 3)), np.arange(6).reshape(2, 3), np.zeros(2, np.int64),
                        object_matrix=np.eye(4), tangents=r.normal(size=(2, 3, 3)), tangent_signs=np.ones((2, 3)))
    attrs = SceneAttributes(Scene(None, [Material("M")], [mesh], [], []), mesh.vertices[mesh.triangles], None)

    def normal(prim, compiled):
        n = len(prim)
        ctx = attrs.context(np.full(n, TRIANGLE, np.int8), np.asarray(prim), np.full(n, .2), np.full(n, .3),
                            HitPoints(direction=-np.ones((3, n)), normal=np.ones((3, n)), shading=np.ones((3, n))),
                            (5, 0), None, TRIANGLE)
        with compiled_for(compiled):
            return normals.normal_map({"Color": np.full((3, n), 0.7), "Strength": np.ones(n)},
                                      {"space": "TANGENT"}, ctx)["Normal"]
    assert np.array_equal(normal([0, 1, 1], False), normal([0, 1, 1], True))
    for compiled in (False, True):
        for prim in ([0, 1, 2], [0, -1, 1]):
            if prim[1] == -1 and not compiled:
                continue            # NumPy's take reads -1 as the last row: only the kernel's own check applies
            with pytest.raises(IndexError):
                normal(prim, compiled)
