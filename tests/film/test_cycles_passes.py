"""Cycles' first-hit and light passes in the tracer (engine/film/passes.py FIRST_HIT, LIGHT, COLOR):
closed forms on a plane, Cycles' Combined identity (Combined = Emission + Environment + the sum over
diffuse, glossy and transmission of Color x (Direct + Indirect)) per material kind, and the image
staying the same bit for bit with any of them on."""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.film.passes import COLOR, FIRST_HIT, LIGHT
from engine.scene.builtin import cornell_scene
from engine.scene.model import DIFFUSE, GLASS, GLOSSY, MIRROR, Camera, Material, Quad, Scene, Sphere

SILENT = dict(log=lambda *a: None)
IDENTITY = ("emission", "environment") + LIGHT + COLOR


def light_sum(passes, leave_out=()):
    """Cycles' identity's right-hand side from the passes (float64)."""
    p = {n: np.asarray(v, np.float64) for n, v in passes.items()}
    total = p["emission"] + p["environment"]
    for k, kind in enumerate(("diffuse", "glossy", "transmission")):
        light = sum(p[f"{kind}_{part}"] for part in ("direct", "indirect") if f"{kind}_{part}" not in leave_out)
        total = total + p[COLOR[k]] * light
    return total


def floor(z=0.0, material=0, size=50.0, index=0):
    s = size
    return Quad("Floor", np.array([(-s, -s, z), (s, -s, z), (s, s, z), (-s, s, z)], dtype=float), material,
                pass_index=index)


def test_plane_from_above_closed_forms():
    """Straight down from 4 m: Normal (0, 0, 1), Position on z = 0 at sample 0, Mist of the distance
    (start 1, depth 8, quadratic), the indices; the sky above the horizon is none of these."""
    cam = Camera.look_at((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), up=(0, 1, 0), lens=30.0)
    mats = [Material("Paint", DIFFUSE, (0.5, 0.5, 0.5), pass_index=6)]
    scene = Scene(cam, mats, quads=[floor(index=4)], resolution=(10, 8), mist=(1.0, 8.0, 2.0))
    p = render(scene, RenderSettings(samples=4, passes=FIRST_HIT, threads=1), **SILENT).passes
    assert np.allclose(p["world_normal"], (0.0, 0.0, 1.0), atol=1e-9)
    assert np.allclose(p["position"][..., 2], 0.0, atol=1e-9)
    assert np.all(p["object_index"] == 4.0) and np.all(p["material_index"] == 6.0)
    # the centre pixels' rays are ~4 m long: mist = ((4 - 1) / 8)^2 at the axis, a little more off it
    centre = p["mist"][3:5, 4:6, 0]
    assert np.all((centre > (3 / 8) ** 2) & (centre < (3.1 / 8) ** 2)), centre
    assert np.all(p["uv"] == 0.0)           # quads have no UVs (Cycles: primitive_uv is 0 without a map)
    assert np.all(p["emission"] == 0.0) and np.all(p["environment"] == 0.0)


def test_mist_control_falloff_matters():
    """The same scene with a linear falloff: a different mist (the pass reads Scene.mist)."""
    cam = Camera.look_at((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), up=(0, 1, 0), lens=30.0)
    mats = [Material("Paint", DIFFUSE, (0.5, 0.5, 0.5))]
    mists = [render(Scene(cam, mats, quads=[floor()], resolution=(4, 4), mist=(1.0, 8.0, f)),
                    RenderSettings(samples=2, passes=("mist",), threads=1), **SILENT).passes["mist"]
             for f in (2.0, 1.0)]
    assert np.allclose(mists[1] ** 2, mists[0], atol=2e-3) and not np.allclose(mists[0], mists[1], atol=0.05)


def identity_scene(kind):
    """A closed box lit by an emitter and the sky, with a sphere of material `kind`."""
    cam = Camera.look_at((0.0, -3.0, 1.2), (0.0, 0.0, 0.6), lens=28.0)
    mats = [Material("Wall", DIFFUSE, (0.7, 0.6, 0.5)), Material("Lamp", DIFFUSE, (0, 0, 0), emission=(6.0, 6.0, 6.0)),
            Material("Ball", kind, (0.9, 0.8, 0.7), roughness=0.3 if kind == GLOSSY else None)]
    lamp = Quad("Lamp", np.array([(-0.3, -0.3, 2.5), (-0.3, 0.3, 2.5), (0.3, 0.3, 2.5), (0.3, -0.3, 2.5)], float), 1)
    return Scene(cam, mats, quads=[floor(), lamp], spheres=[Sphere("Ball", (0.0, 0.0, 0.5), 0.5, 2)],
                 background=(0.2, 0.3, 0.4), resolution=(16, 12))


@pytest.mark.parametrize("kind", [DIFFUSE, GLOSSY, MIRROR, GLASS])
def test_combined_is_the_sum_of_the_light_passes(kind):
    r = render(identity_scene(kind), RenderSettings(samples=4, max_depth=4, passes=IDENTITY, threads=1), **SILENT)
    total = light_sum(r.passes)
    assert np.allclose(total, r.image, rtol=1e-5, atol=1e-5), np.abs(total - r.image).max()
    lit = {n: float(r.passes[n].sum()) for n in IDENTITY}
    expected = {DIFFUSE: "diffuse", GLOSSY: "glossy", MIRROR: "glossy", GLASS: "transmission"}[kind]
    # light through a glass ball is at least two bounces (in and out): Transmission Indirect only
    seen = f"{expected}_indirect" if kind == GLASS else f"{expected}_direct"
    assert lit[seen] > 0 and lit["diffuse_direct"] > 0 and lit["environment"] > 0, lit
    # control: one pass left out breaks the identity
    short = light_sum(r.passes, leave_out=(f"{expected}_indirect",))
    assert not np.allclose(short, r.image, rtol=1e-5, atol=1e-5)


def test_image_is_the_same_with_every_pass_on():
    scene = cornell_scene(resolution=(12, 12))
    plain = render(scene, RenderSettings(samples=4, threads=1), **SILENT).image
    every = render(cornell_scene(resolution=(12, 12)), RenderSettings(samples=4, threads=1, passes=FIRST_HIT + LIGHT + COLOR),
                   **SILENT).image
    assert np.array_equal(plain, every)


def test_glass_colour_splits_by_fresnel():
    """A smooth glass plane seen head-on: Glossy Color = F0 x colour = 0.04 x colour (IOR 1.5),
    Transmission Color = the rest; a diffuse plane: Diffuse Color = its colour, the others 0."""
    cam = Camera.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0), up=(0, 1, 0), lens=200.0)
    for kind, expect in ((GLASS, (0.0, 0.04, 0.96)), (DIFFUSE, (1.0, 0.0, 0.0))):
        mats = [Material("M", kind, (0.5, 0.6, 0.7), ior=1.5)]
        p = render(Scene(cam, mats, quads=[floor()], resolution=(4, 4)),
                   RenderSettings(samples=2, passes=COLOR, threads=1), **SILENT).passes
        for name, share in zip(COLOR, expect):
            assert np.allclose(p[name], share * np.array([0.5, 0.6, 0.7]), atol=2e-3), (kind, name, p[name][0, 0])


def test_cryptomatte_hash_and_coverage():
    """engine/film/cryptomatte.py: MurmurHash3_32 test vectors, the spec's float conversion (never
    NaN, inf or denormal), and a render's ids and coverage: two quads side by side, each pixel
    wholly one (coverage 1) and an edge column shared."""
    from engine.film import cryptomatte as cm
    assert cm.murmur3_32(b"") == 0 and cm.murmur3_32(b"hello") == 0x248BFA47
    assert cm.murmur3_32(b"The quick brown fox jumps over the lazy dog") == 0x2E4FF723
    for h in (0, 0xFFFFFFFF, 0x7F800000, 0x00000001):
        f = np.float32(cm.hash_to_float(h))
        assert np.isfinite(f) and (f == 0 or abs(f) >= np.finfo(np.float32).tiny)
    cam = Camera.look_at((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), up=(0, 1, 0), lens=30.0)
    left = Quad("Left", np.array([(-9, -9, 0), (0, -9, 0), (0, 9, 0), (-9, 9, 0)], float), 0)
    right = Quad("Right", np.array([(0, -9, 0), (9, -9, 0), (9, 9, 0), (0, 9, 0)], float), 1)
    mats = [Material("Red", DIFFUSE, (0.8, 0.1, 0.1)), Material("Blue", DIFFUSE, (0.1, 0.1, 0.8))]
    r = render(Scene(cam, mats, quads=[left, right], resolution=(9, 4)),
               RenderSettings(samples=8, passes=("crypto_object", "crypto_material"), threads=1), **SILENT)
    obj = r.passes["crypto_object"]
    assert obj.shape == (4, 9, 4 * cm.LEVELS)
    assert np.all(obj[:, 0, 0] == np.float32(cm.name_id("Left"))) and np.all(obj[:, 0, 1] == 1.0)
    assert np.all(obj[:, 8, 0] == np.float32(cm.name_id("Right")))
    assert np.allclose(obj[..., 1] + obj[..., 3], 1.0)          # the edge column: two ids sharing it
    assert np.all(r.passes["crypto_material"][:, 0, 0] == np.float32(cm.name_id("Red")))
    meta = dict(cm.manifest_metadata(Scene(cam, mats, quads=[left, right]), "crypto_object"))
    assert '"Left":"%08x"' % cm.name_hash("Left") in next(v for k, v in meta.items() if k.endswith("manifest"))
