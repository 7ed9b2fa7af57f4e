"""HitPoints.taken (engine/nodes/context.py): the fields of HitPoints.take, each taken only when read, and
the contexts of node programs built from them read the same numbers; HitTextures.run_program of every
hit (no takes) and engine/materials/textures.py `whole` give what the takes and the copy gave."""
import numpy as np

from engine.geometry.scene_geometry import TRIANGLE
from engine.materials.textures import whole
from engine.nodes.context import HitPoints, SceneAttributes
from engine.nodes.evaluator import run
from engine.scene.model import Material, Scene, TriangleMesh
from engine.scene.programs import Link, Program, ProgramNode


class Counted(np.ndarray):
    """An array that counts its takes."""
    takes = 0

    def take(self, *a, **k):
        Counted.takes += 1
        return np.asarray(self).take(*a, **k)


def points(rng, n):
    rows = {name: rng.normal(size=(3, n)) for name in ("point", "direction", "normal", "shading")}
    rows.update(depth=rng.integers(0, 4, n).astype(np.float64), ray_kind=rng.integers(0, 4, n), distance=rng.random(n))
    return HitPoints(**{k: v.view(Counted) for k, v in rows.items()})


def test_taken_reads_the_fields_of_take_and_takes_only_those_read():
    rng = np.random.default_rng(1)
    p = points(rng, 50)
    idx = np.sort(rng.choice(50, 20, replace=False))
    eager = p.take(idx)
    Counted.takes = 0
    lazy = p.taken(idx)
    assert Counted.takes == 0
    assert np.array_equal(lazy.point, eager.point) and Counted.takes == 1
    assert np.array_equal(lazy.point, eager.point) and Counted.takes == 1         # kept
    assert all(lazy.given(f) for f in HitPoints.FIELDS) and Counted.takes == 1
    for f in HitPoints.FIELDS:
        assert np.array_equal(getattr(lazy, f), getattr(eager, f))
    assert not np.array_equal(p.taken(idx[::-1]).point, eager.point)                # control: another index
    assert not HitPoints(point=None).taken(idx).given("direction")


def scene_attributes(rng):
    verts = rng.normal(size=(6, 3))
    mesh = TriangleMesh("M", verts, np.array([[0, 1, 2], [3, 4, 5]]), np.zeros(2, np.int64))
    scene = Scene(None, [Material("M")], [mesh], [], [])
    return SceneAttributes(scene, verts[mesh.triangles], None)


def program(output):
    coords = ProgramNode("ShaderNodeTexCoord", "Coords", {"_outputs": [output]})
    return Program([coords], (0, output, "VECTOR"), "RGBA")


def test_contexts_of_taken_points_give_the_numbers_of_take():
    rng = np.random.default_rng(2)
    attrs = scene_attributes(rng)
    n = 40
    kind, prim = np.full(n, TRIANGLE, np.int8), rng.integers(0, 2, n)
    b1, b2 = rng.random(n) * 0.5, rng.random(n) * 0.5
    p = points(rng, n)
    idx = np.flatnonzero(rng.random(n) < 0.5)
    args = (kind[idx], prim[idx], b1[idx], b2[idx])
    light_path = ProgramNode("ShaderNodeLightPath", "Path", {"_outputs": ["Ray Depth", "Is Shadow Ray"]})
    for prog in (program("Object"), program("Generated"), program("Reflection"),
                 Program([light_path], (0, "Ray Depth", "VALUE"), "VALUE")):
        eager = run(prog, attrs.context(*args, p.take(idx), (5, 0), None, TRIANGLE))
        lazy = run(prog, attrs.context(*args, p.taken(idx), (5, 0), None, TRIANGLE))
        assert eager.dtype == lazy.dtype and np.array_equal(eager, lazy)


def test_whole_is_the_copy_with_every_value_written():
    rng = np.random.default_rng(3)
    values = rng.random((3, 8))
    new = rng.random((3, 8))
    copy = np.array(values)
    copy[:, np.arange(8)] = new
    out = whole(values, new)
    assert out is new and np.array_equal(out, copy)
    grey = rng.random(8)                                         # (N,) written into rows: a copy
    out = whole(values, grey)
    assert out is not grey and out.shape == (3, 8) and np.array_equal(out, np.broadcast_to(grey, (3, 8)))
    single = rng.random((3, 8)).astype(np.float32)               # another dtype: a float64 copy
    out = whole(values, single)
    assert out.dtype == np.float64 and np.array_equal(out, single.astype(np.float64))
