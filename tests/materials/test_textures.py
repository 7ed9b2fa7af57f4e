"""Image textures (engine/materials/textures.py): lookups against hand-computed texels, the wrap modes, the
sRGB decode, missing images, scene files, and textured emitters sampled as lights."""
import copy

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.integrators.effects import plan_effects
from engine.scene.model import Camera, Material, Quad, Scene, TriangleMesh
from engine.core.errors import SceneError
from engine.scene.files import load_scene, save_scene
from engine.scene.textures import ImageTexture, TextureSlot
from engine.materials.textures import TextureSet, lookup, read_image, srgb_to_linear

# A 4 x 2 image, texel (x, y) = 10 y + x (row 0 = the bottom row, v = 0).
GRID = (10.0 * np.arange(2)[:, None] + np.arange(4)[None, :])[:, :, None].astype(np.float32)


def at(u, v, interpolation="Closest", extension="REPEAT", pixels=GRID):
    return lookup(pixels, np.atleast_1d(np.asarray(u, float)), np.atleast_1d(np.asarray(v, float)),
                  interpolation, extension)[:, 0]


def test_closest_reads_the_texel_under_the_point():
    # u in [0.25, 0.5) is column 1, v in [0.5, 1) is row 1 (the top row).
    assert at([0.0, 0.3, 0.74, 0.99], [0.1, 0.6, 0.2, 0.99]).tolist() == [0, 11, 2, 13]


def test_linear_is_bilinear_between_texel_centres():
    # Texel centres are at ((x + 0.5) / 4, (y + 0.5) / 2): there the value is the texel itself.
    assert at(0.375, 0.25, "Linear").tolist() == [1.0]
    # u = 0.5 is halfway between columns 1 and 2; v = 0.5 halfway between rows 0 and 1.
    assert at(0.5, 0.25, "Linear").tolist() == [1.5]
    assert at(0.375, 0.5, "Linear").tolist() == [6.0]
    # A general point by hand: x = 0.45 * 4 - 0.5 = 1.3, y = 0.6 * 2 - 0.5 = 0.7.
    tx, ty = 0.3, 0.7
    expected = (1 - ty) * ((1 - tx) * 1 + tx * 2) + ty * ((1 - tx) * 11 + tx * 12)
    assert at(0.45, 0.6, "Linear")[0] == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize("extension, u, expected", [
    ("REPEAT", 1.1, 0), ("REPEAT", -0.1, 3), ("REPEAT", 2.6, 2),
    ("EXTEND", 1.6, 3), ("EXTEND", -3.0, 0),
    ("CLIP", 1.1, 0), ("CLIP", -0.01, 0), ("CLIP", 0.9, 3),
    ("MIRROR", 1.1, 3), ("MIRROR", 1.3, 2), ("MIRROR", -0.1, 0)])
def test_wrap_modes_closest(extension, u, expected):
    assert at(u, 0.25, "Closest", extension)[0] == expected


def test_wrap_modes_linear_at_the_border():
    # u = 0: x = -0.5, halfway between texel -1 and texel 0.
    assert at(0.0, 0.25, "Linear", "REPEAT")[0] == pytest.approx(0.5 * (3 + 0))
    assert at(0.0, 0.25, "Linear", "EXTEND")[0] == pytest.approx(0.0)
    grey = np.full((2, 4, 1), 0.8, np.float32)
    assert at(0.0, 0.25, "Linear", "CLIP", grey)[0] == pytest.approx(0.4)    # outside texels read 0
    # Cycles: the border texels fade out over the half texel beyond [0, 1] (x = 1.05 * 4 - 0.5 = 3.7)
    assert at(1.05, 0.25, "Linear", "CLIP", grey)[0] == pytest.approx(0.3 * 0.8)
    assert at(1.13, 0.25, "Linear", "CLIP", grey)[0] == 0.0                  # a full half texel out
    assert at(0.5, 0.25, "Linear", "CLIP", grey)[0] == pytest.approx(0.8)


def test_srgb_decode_matches_the_formula():
    c = np.array([0.0, 0.01, 0.04045, 0.0405, 0.2, 0.5, 0.8, 1.0])
    expected = [x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4 for x in c]
    assert np.allclose(srgb_to_linear(c), expected, rtol=1e-12, atol=0)
    assert srgb_to_linear(0.5) == pytest.approx(0.21404, abs=1e-5)
    # Continuous at the joint (both pieces give 0.0031308 there, to 3e-9).
    assert srgb_to_linear(0.04045) == pytest.approx(srgb_to_linear(0.04045 + 1e-12), abs=1e-8)


def texture_scene(textures, slot, **material):
    mats = [Material("Textured", color=(0.8, 0.2, 0.1), color_texture=slot, **material)]
    mesh = TriangleMesh("Card", np.array([(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)], float),
                        np.array([[0, 1, 2], [0, 2, 3]]), [0, 0],
                        uvs=np.array([[(0, 0), (1, 0), (1, 1)], [(0, 0), (1, 1), (0, 1)]], float))
    return Scene(Camera.look_at((0.5, -3, 0.5), (0.5, 0, 0.5)), mats, [mesh], background=(1, 1, 1),
                 resolution=(8, 8), textures=textures)


def test_8bit_srgb_is_interpolated_then_decoded_and_float_decoded_first():
    """Cycles' 'compress as sRGB': byte sRGB images blend stored values, float images linear ones."""
    two = np.array([[[0.0], [1.0]]], np.float32)         # 1 x 2: black, white
    slot = TextureSlot(0, "Linear", "EXTEND")
    for is_float, expected in ((False, srgb_to_linear(0.5)), (True, 0.5)):
        scene = texture_scene([ImageTexture("ramp", pixels=two, colorspace="sRGB", is_float=is_float)], slot)
        value = TextureSet(scene).evaluate(slot, np.array([0.5]), np.array([0.5]))
        assert value[:, 0] == pytest.approx([expected] * 3)
    scene = texture_scene([ImageTexture("ramp", pixels=two, colorspace="Non-Color")], slot)
    assert TextureSet(scene).evaluate(slot, np.array([0.5]), np.array([0.5]))[:, 0] == pytest.approx([0.5] * 3)
    grey = np.array([[[0.2], [0.7]]], np.float32)
    closest = TextureSlot(0, "Closest", "EXTEND", scale=(1, 2, 3))
    scene = texture_scene([ImageTexture("grey", pixels=grey, colorspace="sRGB")], closest)
    value = TextureSet(scene).evaluate(closest, np.array([0.2, 0.9]), np.array([0.5, 0.5]))
    assert value == pytest.approx(np.outer([1, 2, 3], srgb_to_linear([0.2, 0.7])))


def test_missing_image_warns_with_material_and_image_and_renders_the_unlinked_colour(tmp_path):
    missing = str(tmp_path / "nowhere.png")
    slot = TextureSlot(0, "Linear", "REPEAT")
    scene = texture_scene([ImageTexture("Wood", path=missing)], slot)
    warnings = scene.validate()
    assert any("Material 'Textured'" in w and "image 'Wood'" in w and "nowhere.png" in w for w in warnings)
    plain = copy.deepcopy(scene)
    plain.materials[0].color_texture, plain.textures = None, []
    logs = []
    a = render(scene, RenderSettings(samples=2, seed=1), log=logs.append)
    b = render(plain, RenderSettings(samples=2, seed=1), log=lambda *x: None)
    assert np.array_equal(a.image, b.image)
    # negative control: a readable texture changes the picture
    scene.textures = [ImageTexture("Wood", pixels=np.full((2, 2, 3), 0.1, np.float32), colorspace="Non-Color")]
    c = render(scene, RenderSettings(samples=2, seed=1), log=lambda *x: None)
    assert not np.allclose(a.image, c.image)


def test_bad_texture_data_is_a_scene_error_naming_it():
    slot = TextureSlot(3, "Linear", "REPEAT")
    with pytest.raises(SceneError, match="Material 'Textured': colour texture index 3 out of range"):
        texture_scene([ImageTexture("a", pixels=np.zeros((1, 1, 3), np.float32))], slot).validate()
    with pytest.raises(SceneError, match="Material 'Textured': unknown texture extension 'WRAP'"):
        texture_scene([ImageTexture("a", pixels=np.zeros((1, 1, 3), np.float32))],
                      TextureSlot(0, "Linear", "WRAP")).validate()
    for bad in (np.full((2, 2, 3), np.nan, np.float32), np.zeros((0, 2, 3)), np.array([["a"]])):
        with pytest.raises(SceneError, match="Image 'a': pixels must be a finite"):
            texture_scene([ImageTexture("a", pixels=bad)], TextureSlot(0)).validate()
    scene = texture_scene([ImageTexture("a", pixels=np.zeros((1, 1, 3), np.float32))], TextureSlot(0))
    scene.meshes[0].uvs = np.zeros((2, 2, 2))
    with pytest.raises(SceneError, match="Object 'Card': UVs must be 3 finite"):
        scene.validate()


def test_image_files_are_read_bottom_row_first(tmp_path):
    import OpenImageIO as oiio
    top_first = np.zeros((2, 3, 3), np.float32)
    top_first[0] = (1.0, 0.0, 0.0)                   # the file's first (top) row is red
    path = str(tmp_path / "rows.exr")
    assert oiio.ImageBuf(top_first).write(path)
    pixels, is_float = read_image(path)
    assert is_float and pixels.shape == (2, 3, 3)
    assert pixels[1, :, 0].tolist() == [1.0] * 3 and pixels[0, :, 0].tolist() == [0.0] * 3
    for fmt, floating in (("uint8", False), ("uint16", True)):     # Cycles: only 8-bit stays bytes
        buf = oiio.ImageBuf(oiio.ImageSpec(3, 2, 3, fmt))
        buf.set_pixels(oiio.ROI(), top_first)
        png = str(tmp_path / f"rows_{fmt}.png")
        assert buf.write(png)
        pixels, is_float = read_image(png)
        assert is_float == floating and pixels[1, :, 0].tolist() == [1.0] * 3


def test_effect_plan_reports_textures_only_where_there_are_some():
    slot = TextureSlot(0)
    scene = texture_scene([ImageTexture("Tiles", pixels=np.ones((1, 1, 3), np.float32))], slot)
    plan = plan_effects(scene, RenderSettings())
    assert plan.textures and "'Textured'" in plan.reason["textures"]
    scene.materials[0].color_texture = None
    plan = plan_effects(scene, RenderSettings())
    assert not plan.textures and "no image textures" in plan.reason["textures"]


def test_scene_file_round_trip_keeps_textures_and_uvs(tmp_path):
    import OpenImageIO as oiio
    png = tmp_path / "tex.png"
    rgb = (np.indices((4, 4)).sum(axis=0) % 2)[:, :, None] * np.array([200, 50, 20], np.uint8)
    assert oiio.ImageBuf(np.ascontiguousarray(rgb.astype(np.uint8))).write(str(png))
    scene = texture_scene([ImageTexture("Packed", pixels=np.random.default_rng(1).random((3, 5, 3), np.float32)),
                           ImageTexture("File", path="tex.png"),
                           ImageTexture("Bytes", pixels=np.arange(24, dtype=np.uint8).reshape(2, 3, 4))],
                          TextureSlot(1, "Closest", "CLIP"),
                          emission=(0, 0, 0), emission_texture=TextureSlot(0, "Linear", "MIRROR", (2, 2, 2)))
    scene.textures[1].path = str(png)
    path = str(tmp_path / "scene.json")
    save_scene(scene, path)
    again = load_scene(path)
    assert [t.name for t in again.textures] == ["Packed", "File", "Bytes"]
    assert np.array_equal(again.textures[0].pixels, scene.textures[0].pixels)
    assert again.textures[2].pixels.dtype == np.uint8 and np.array_equal(again.textures[2].pixels,
                                                                         scene.textures[2].pixels)
    assert again.textures[1].path == str(png)
    assert again.materials[0].color_texture == scene.materials[0].color_texture
    assert again.materials[0].emission_texture == scene.materials[0].emission_texture
    assert np.array_equal(np.reshape(again.meshes[0].uvs, (-1, 3, 2)), scene.meshes[0].uvs)
    a = render(scene, RenderSettings(samples=2, seed=3), log=lambda *x: None)
    b = render(again, RenderSettings(samples=2, seed=3), log=lambda *x: None)
    assert np.array_equal(a.image, b.image)


# -- textured emitters as lights ------------------------------------------------------------------
def lamp_scene(textured: bool, receiver_x=-0.25):
    """A floor under a 1 m square lamp 1 m up whose left half emits 2 and right half nothing: as an
    emission texture (2 x 1 texels, Closest) on one quad, or as two quads.  A long lens sees the
    floor point under x = receiver_x only (floor_under_square_light in tests/scenes.py)."""
    mats = [Material("Floor", color=(0.8, 0.8, 0.8)), Material("Dark", color=(0, 0, 0)),
            Material("Lamp", color=(0, 0, 0), emission=(2, 2, 2))]
    big = 50.0
    floor = Quad("Floor", np.array([(-big, -big, 0), (big, -big, 0), (big, big, 0), (-big, big, 0)]), 0)

    def card(name, x0, x1, mat, uvs=None):
        v = np.array([(x0, -0.5, 1), (x0, 0.5, 1), (x1, 0.5, 1), (x1, -0.5, 1)], float)
        return TriangleMesh(name, v, np.array([[0, 1, 2], [0, 2, 3]]), [mat, mat], uvs=uvs)
    textures = []
    if textured:
        mats.append(Material("Texture lamp", color=(0, 0, 0),
                             emission_texture=TextureSlot(0, "Closest", "EXTEND")))
        textures = [ImageTexture("Half", pixels=np.array([[[2.0] * 3, [0.0] * 3]], np.float32),
                                 colorspace="Non-Color", is_float=True)]
        corners = [(0, 0), (0, 1), (1, 1), (1, 0)]       # u runs along x, from x0 to x1
        uvs = np.array([[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]], float)
        meshes = [card("Lamp", -0.5, 0.5, 3, uvs)]
    else:
        meshes = [card("Lamp left", -0.5, 0.0, 2), card("Lamp right", 0.0, 0.5, 1)]
    cam = Camera.look_at((receiver_x, 0, 0.5), (receiver_x, 0, 0), up=(0, 1, 0), lens=20000.0)
    return Scene(cam, mats, meshes, quads=[floor], resolution=(4, 4), textures=textures)


def run_means(scene, seeds, **kw):
    return np.array([render(scene, RenderSettings(samples=256, seed=s, max_depth=1, **kw),
                            log=lambda *x: None).image.mean() for s in seeds])


@pytest.mark.parametrize("estimator, shadow_rays", [("mis", 1), ("solid-angle", 1), ("report", 1), ("mis", 0)])
def test_textured_emitter_equals_the_same_light_made_of_two_quads(estimator, shadow_rays):
    """Light samples and emission hits read the texture at their point: the same expectation as two
    separate quads (Welch z over 16 seeds each, |z| < 4.5); pdfs come from the geometry (MIS intact)."""
    kw = dict(estimator=estimator, shadow_rays=shadow_rays)
    a = run_means(lamp_scene(True), range(1, 17), **kw)
    b = run_means(lamp_scene(False), range(101, 117), **kw)
    z = (a.mean() - b.mean()) / np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b) + 1e-30)
    print(f"{estimator}/{shadow_rays}: textured {a.mean():.5f} two quads {b.mean():.5f} z={z:+.2f}")
    assert abs(z) < 4.5


def test_textured_emitter_control_mean_radiance_is_caught(monkeypatch):
    """Negative control: light samples that use the texture's mean radiance instead of the texel."""
    from engine.materials.textures import HitTextures
    monkeypatch.setattr(HitTextures, "light_radiance", lambda self, radiance, light, point: radiance)
    a = run_means(lamp_scene(True), range(1, 7), estimator="solid-angle")
    b = run_means(lamp_scene(False), range(101, 107), estimator="solid-angle")
    z = (a.mean() - b.mean()) / np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b) + 1e-30)
    print(f"mean radiance: textured {a.mean():.5f} two quads {b.mean():.5f} z={z:+.2f}")
    assert abs(z) > 4.5


def test_octree_and_brute_force_read_the_same_texels_as_embree():
    """The UVs come from the accelerator's barycentrics: every mode renders the same picture."""
    checker = (np.indices((8, 8)).sum(axis=0) % 2)[:, :, None].repeat(3, axis=2).astype(np.float32)
    scene = texture_scene([ImageTexture("Checker", pixels=checker, colorspace="Non-Color")],
                          TextureSlot(0, "Closest", "REPEAT"))
    scene.resolution = (24, 24)
    images = {a: render(copy.deepcopy(scene), RenderSettings(samples=4, seed=2, accelerator=a),
                        log=lambda *x: None).image for a in ("embree", "octree", "brute")}
    mean = images["embree"].mean()
    for a in ("octree", "brute"):
        assert np.abs(images[a] - images["embree"]).mean() < 0.01 * mean, a
    flipped = copy.deepcopy(scene)
    flipped.textures[0].pixels = checker[::-1].copy()              # negative control: the other parity
    other = render(flipped, RenderSettings(samples=4, seed=2, accelerator="octree"), log=lambda *x: None).image
    assert np.abs(other - images["embree"]).mean() > 0.1 * mean


def test_unreadable_image_file_warns_and_renders_the_unlinked_colour(tmp_path):
    bad = tmp_path / "broken.png"
    bad.write_bytes(b"not a png at all")
    scene = texture_scene([ImageTexture("Broken", path=str(bad))], TextureSlot(0))
    logs = []
    result = render(scene, RenderSettings(samples=1), log=logs.append)
    warning = [line for line in logs if "broken.png" in line]
    assert warning and "Material 'Textured'" in warning[0] and "image 'Broken'" in warning[0], logs
    assert np.isfinite(result.image).all()
    assert any("broken.png" in w for w in result.warnings)          # what a worker sends to Blender


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["materials"][0].update(color_texture={"texture": "Nope"}),
     "Material 'Textured': color_texture: unknown texture 'Nope'"),
    (lambda d: d["materials"][0].update(color_texture=7), "Material 'Textured': color_texture: must be a JSON object"),
    (lambda d: d["textures"][0].pop("pixels"), "Image 'Packed': path is missing"),
    (lambda d: d["textures"][0].update(pixels="@gone"), "Image 'Packed': pixels: array 'gone' not found"),
    (lambda d: d["materials"][0]["color_texture"].update(interpolation="Cubic"),
     "Material 'Textured': unknown texture interpolation 'Cubic'"),
])
def test_bad_texture_fields_in_scene_files_are_one_line(tmp_path, edit, message):
    import json
    scene = texture_scene([ImageTexture("Packed", pixels=np.ones((2, 2, 3), np.float32))], TextureSlot(0))
    path = tmp_path / "scene.json"
    save_scene(scene, str(path))
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data))
    with pytest.raises(SceneError, match=message.replace("(", r"\(")):
        load_scene(str(path)).validate()


def test_albedo_pass_reads_textured_colour_and_emission():
    """The denoising albedo (engine/film/passes.py) of a textured surface is the texel, not the unlinked
    colour: a card whose left half (u < 0.5) is texel 0 and right half texel 1."""
    pixels = np.array([[[0.9, 0.1, 0.1], [0.1, 0.1, 0.9]]], np.float32)
    for role in ("color_texture", "emission_texture"):
        slot = TextureSlot(0, "Closest", "EXTEND")
        scene = texture_scene([ImageTexture("Two", pixels=pixels, colorspace="Non-Color", is_float=True)],
                              slot if role == "color_texture" else None)
        scene.background = (0.0, 0.0, 0.0)
        if role == "emission_texture":
            scene.materials[0] = Material("Textured", color=(0, 0, 0), emission_texture=slot)
        scene.camera = Camera.look_at((0.5, -3, 0.5), (0.5, 0, 0.5), lens=300.0)        # the card fills the view
        albedo = render(scene, RenderSettings(samples=4, passes=("albedo",)), log=lambda *x: None).passes["albedo"]
        left, right = albedo[:, :3].mean(axis=(0, 1)), albedo[:, -3:].mean(axis=(0, 1))
        assert left == pytest.approx(pixels[0, 0], abs=1e-6) and right == pytest.approx(pixels[0, 1], abs=1e-6), role


# -- a float input read once per span of hits (HitLookup.input) --------------------------------------
def test_views_of_one_span_read_a_float_input_once(monkeypatch):
    """The Principled BSDF's lobes and layer weights read a roughness texture through views of one
    span (ShadingPoint.__getitem__): the texture is looked up once, and every view gets the numbers
    of a fresh read.  Other hits, other material ids and takes read afresh (controls)."""
    from engine.geometry.scene_geometry import TRIANGLE
    from engine.materials.textures import HitTextures, HitLookup
    pixels = np.random.default_rng(1).random((3, 5, 1)).astype(np.float32)
    slot = TextureSlot(0, "Linear", "REPEAT")
    scene = texture_scene([ImageTexture("rough", pixels=pixels, colorspace="Non-Color", is_float=True)], None,
                          input_textures={"roughness": slot})
    scene.materials.append(Material("Plain", color=(0.5, 0.5, 0.5)))
    triangles = np.array([m.vertices[t] for m in scene.meshes for t in m.triangles])
    hits = HitTextures(TextureSet(scene), scene, triangles, np.zeros(2, np.int64))
    rng = np.random.default_rng(2)
    n = 40
    kind, prim = np.full(n, TRIANGLE, np.int8), rng.integers(0, 2, n)
    b1 = rng.random(n) * 0.5
    b2 = rng.random(n) * 0.5
    material = rng.integers(0, 2, n)
    values = np.array([0.3, 0.6]).take(material)
    reads = []
    original = TextureSet.value
    monkeypatch.setattr(TextureSet, "value", lambda self, *a: reads.append(1) or original(self, *a))
    fresh = hits.input("roughness", values, material, kind, prim, b1, b2)
    assert len(reads) == 1 and not np.array_equal(fresh, values)
    lookup = HitLookup(hits, kind, prim, b1, b2)
    span = slice(5, 30)
    first = lookup[span].input("roughness", values[span], material[span])
    again = lookup[span].input("roughness", values[span] * 2.0, material[span])     # another view, other fallback
    assert len(reads) == 2
    assert np.array_equal(first, fresh[span])
    textured = material[span] == 0
    assert np.array_equal(again[textured], fresh[span][textured])
    assert np.array_equal(again[~textured], 2.0 * values[span][~textured])
    # Controls: another span, other material ids at the same hits, a take: each reads again.
    lookup[slice(5, 31)].input("roughness", values[5:31], material[5:31])
    assert len(reads) == 3
    lookup[span].input("roughness", values[span], 1 - material[span])
    assert len(reads) == 4
    taken = lookup.take(np.arange(5, 30))
    assert np.array_equal(taken.input("roughness", values[span], material[span]), fresh[span])
    assert len(reads) == 5


def test_a_take_of_a_lookup_gathers_what_is_read_when_read():
    """HitLookup.take: each array gathered on first read, equal to an eager take's; a take of a take
    gathers from the first lookup at the composed index; the lookup's node-program points too.  An
    input no material textures is read without gathering any array.  Control: the composed index in
    the other order reads other hits."""
    from engine.geometry.scene_geometry import TRIANGLE
    from engine.materials.textures import HitTextures, HitLookup
    from engine.nodes.context import HitPoints
    pixels = np.random.default_rng(1).random((3, 5, 1)).astype(np.float32)
    scene = texture_scene([ImageTexture("rough", pixels=pixels, colorspace="Non-Color", is_float=True)], None,
                          input_textures={"roughness": TextureSlot(0, "Linear", "REPEAT")})
    triangles = np.array([m.vertices[t] for m in scene.meshes for t in m.triangles])
    hits = HitTextures(TextureSet(scene), scene, triangles, np.zeros(2, np.int64))
    rng = np.random.default_rng(4)
    n = 30
    kind, prim, b1, b2 = np.full(n, TRIANGLE, np.int8), rng.integers(0, 2, n), rng.random(n) * 0.5, rng.random(n) * 0.5
    points = HitPoints(point=rng.random((3, n)), depth=rng.integers(0, 4, n))
    lookup = HitLookup(hits, kind, prim, b1, b2, points)
    outer, inner = rng.integers(0, n, 20), rng.integers(0, 20, 12)
    taken = lookup.take(outer)
    assert "prim" not in vars(taken)                                    # nothing gathered yet
    assert np.array_equal(taken.prim, prim.take(outer)) and "b1" not in vars(taken)
    twice = taken.take(inner)
    for name in ("kind", "prim", "b1", "b2"):
        assert np.array_equal(getattr(twice, name), getattr(lookup, name).take(outer).take(inner))
    assert np.array_equal(twice.points.point, points.point.take(outer, axis=1).take(inner, axis=1))
    assert np.array_equal(twice.points.depth, points.depth.take(outer).take(inner))
    assert twice.points.normal is None
    # an input no material textures: the values themselves, no array gathered
    fresh = lookup.take(outer)
    values = rng.random(20)
    assert fresh.input("metallic", values, np.zeros(20, np.int64)) is values and "kind" not in vars(fresh)
    tangents = rng.random((3, 20))
    assert fresh.tangent(tangents, np.zeros(20, np.int64)) is tangents and "kind" not in vars(fresh)   # no mesh tangents
    assert not np.array_equal(fresh.input("roughness", values, np.zeros(20, np.int64)), values)
    # control: the indices composed the other way round are other hits
    assert not np.array_equal(twice.b1, b1.take(inner))
    assert not np.array_equal(twice.b1, b1.take(outer.take(np.arange(12))))


def test_by_material_groups_hits_as_np_unique_does():
    from engine.materials.textures import by_material, picked
    rng = np.random.default_rng(9)
    for mat in (rng.integers(0, 6, 200), np.full(30, 4), np.array([2, 0, 2, 5]), np.zeros(0, np.int64)):
        groups = by_material(mat)
        assert [int(m) for m, _ in groups] == np.unique(mat).tolist()
        for m, mine in groups:
            assert np.array_equal(picked(np.arange(len(mat)), mine), np.flatnonzero(mat == m))
    # control: a wrong grouping is told apart
    assert [int(m) for m, _ in by_material(np.array([1, 3]))] != [1]
