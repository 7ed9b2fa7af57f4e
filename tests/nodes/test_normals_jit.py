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
    calls, original = [], normals.normal_map

    def recording(inputs, props, ctx):
        if len(calls) < limit:
            names = ("normal", "backfacing", "tangent", "tangent_sign", "has_tangent", "tangent_base")
            kept = NodeContext(ctx.n, ctx.cycles_version, {k: np.array(ctx.attr(k)) for k in names})
            calls.append(({k: np.array(v) for k, v in inputs.items()}, dict(props), kept))
        return original(inputs, props, ctx)
    table = kernels()                         # the evaluator's table of kernels, built once
    table["ShaderNodeNormalMap"] = recording
    try:
        api.render(ground(version), RenderSettings(samples=2, threads=1, backend="numpy"), log=lambda m: None)
    finally:
        table["ShaderNodeNormalMap"] = original
    return calls


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
