"""The compiled first half of HitTextures.light_radiance (engine/materials/textures_jit.py light_points:
which light samples lie on a textured emitter, the triangle of its pair, the barycentrics and UVs there)
against the NumPy path of engine/materials/textures.py: bit for bit on the light samples of NumPy
renders (an image-textured lamp, a lamp with an emission program, and beside it a lamp without either)
and on hand-made points (outside both triangles, on the diagonal, -0.0, NaN, lights without texture);
a control shows the comparison sees a point moved by one ulp."""
import dataclasses

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.materials.textures import HitTextures
from engine.scene.programs import Link, Program, ProgramNode
from tests.backend_capture import require_compiled
from tests.materials.test_textures import lamp_scene


def twin():
    require_compiled()
    from engine.materials import textures_jit
    return textures_jit


def lamps(program: bool, alone: bool = False):
    """lamp_scene's image-textured lamp, beside it a lamp whose emission is a node program (its
    Generated coordinates x 12) or plain, and a plain lamp of another material (light numbers
    without textured triangles); `alone`: the program's lamp only (one program at every sample)."""
    scene = lamp_scene(True)
    lamp = scene.meshes[0]
    mats = list(scene.materials)
    if program:
        generated = ProgramNode("ShaderNodeTexCoord", "Coords", {"_outputs": ["Generated"]})
        scale = ProgramNode("TNCG15Scale", "", {}, {"Color": Link(0, "Generated", "VECTOR", "RGBA"), "Strength": 12.0})
        mats[2] = dataclasses.replace(mats[2], programs={"emission": Program([generated, scale], (1, "Color", "RGBA"))})
    mats.append(dataclasses.replace(mats[2], name="Plain", programs={}))
    second = dataclasses.replace(lamp, name="Second lamp", vertices=lamp.vertices + np.array([0.0, 1.5, 0.0]),
                                 material_ids=[2, 2], uvs=None)
    plain = dataclasses.replace(lamp, name="Plain lamp", vertices=lamp.vertices - np.array([0.0, 1.5, 0.0]),
                                material_ids=[len(mats) - 1] * 2, uvs=None)
    return dataclasses.replace(scene, materials=mats, meshes=[second] if alone else [lamp, second, plain])


def recorded(scene):
    """[(HitTextures, radiance, light, point)] of light_radiance in a NumPy render."""
    calls, original = [], HitTextures.light_radiance

    def recording(self, radiance, light, point):
        calls.append((self, radiance.copy(), light.copy(), point.copy()))
        return original(self, radiance, light, point)
    HitTextures.light_radiance = recording
    try:
        render(scene, RenderSettings(samples=16, seed=2, threads=1, backend="numpy", max_depth=2), log=lambda *a: None)
    finally:
        HitTextures.light_radiance = original
    return calls


def both(textures, radiance, light, point):
    """light_radiance on the NumPy path and on the compiled one (the same HitTextures)."""
    jit = twin()
    saved = textures.textures.compiled
    try:
        textures.textures.compiled = None
        reference = textures.light_radiance(radiance, light, point)
        textures.textures.compiled = jit
        return reference, textures.light_radiance(radiance, light, point)
    finally:
        textures.textures.compiled = saved


def same(a, b) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("program, alone", [(False, False), (True, False), (True, True)])
def test_recorded_light_samples_are_the_same(program, alone):
    calls = recorded(lamps(program, alone))
    assert sum(len(c[2]) for c in calls) > 100
    textured = 0
    for textures, radiance, light, point in calls:
        reference, compiled = both(textures, radiance, light, point)
        assert same(reference, compiled)
        textured += int((reference != radiance).any(axis=0).sum())
    assert textured > 50                             # the texture or program changed many samples


def hand_made(textures, rng):
    """Light numbers (every light, one beyond them) and points on, around and far off the lamps."""
    n = 400
    light = rng.integers(0, len(textures.light_a) + 1, n)
    tri = textures.barycentrics
    k = np.where(textures.light_a.take(np.minimum(light, len(textures.light_a) - 1)) >= 0,
                 textures.light_a.take(np.minimum(light, len(textures.light_a) - 1)), 0)
    b1, b2 = rng.uniform(-0.5, 1.5, n), rng.uniform(-0.5, 1.5, n)
    b1[:40], b2[:40] = 0.5, 0.5                      # the pair's shared diagonal
    point = tri.v0[:, k] + b1 * tri.e1[:, k] + b2 * tri.e2[:, k]
    point[:, 40:60] = -0.0
    point[0, 60:65] = np.nan
    point[:, 65:70] *= 1e300
    return light, point


def test_hand_made_points_are_the_same():
    calls = recorded(lamps(True))
    textures, radiance, _, _ = calls[0]
    rng = np.random.default_rng(3)
    light, point = hand_made(textures, rng)
    radiance = rng.random((3, len(light)))
    with np.errstate(invalid="ignore", over="ignore"):
        reference, compiled = both(textures, radiance, light, point)
    assert same(reference, compiled)
    jit = twin()
    sel, tri, material, b1, b2, u, v, rows = jit.light_points(light, point, textures.light_a, textures.light_b,
                                                              textures.emitting, textures.material_ids,
                                                              textures.barycentrics.terms, textures.tri_uv,
                                                              textures.corners)
    assert len(sel) < len(light) and (tri == textures.emitting[1]).any() and (tri == textures.emitting[0]).any()
    # the positions: the numbers and the layout of the node context's own at these points
    from engine.geometry.scene_geometry import TRIANGLE
    ctx = textures.attributes.context(np.full(len(sel), TRIANGLE, np.int8), tri, b1, b2, None, (5, 0), None, TRIANGLE)
    position = ctx.attr("position")
    assert same(rows, position) and rows.strides == position.strides


def test_control_an_ulp_is_seen():
    calls = recorded(lamps(True))
    textures, radiance, light, point = max(calls, key=lambda c: len(c[2]))
    jit = twin()
    args = (textures.light_a, textures.light_b, textures.emitting, textures.material_ids, textures.barycentrics.terms,
            textures.tri_uv)
    _, _, _, b1, b2, u, _, p = jit.light_points(light, point, *args, textures.corners)
    _, _, _, c1, c2, w, _, q = jit.light_points(light, np.nextafter(point, np.inf), *args, textures.corners)
    assert not same(b1, c1) or not same(b2, c2)
    assert not same(u, w) and not same(p, q)
