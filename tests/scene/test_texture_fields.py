"""engine/scene/texture_fields.py: the scene file's image textures and texture slots, written by hand
as the format documents them, read, written again by engine/scene/files.py and read back the same;
and every wrong entry is a SceneError naming the image or the material."""
import json

import numpy as np
import pytest

from engine.core.errors import SceneError
from engine.scene.fields import Fields
from engine.scene.files import load_scene, save_scene
from engine.scene.texture_fields import read_slot, read_textures, slot_json, textures_json
from engine.scene.textures import TextureSlot

QUAD = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]


def write_scene(tmp_path, textures, color_texture, arrays=None, name="scene"):
    """A scene file with one textured mesh; ``arrays`` go to the NPZ beside it."""
    data = {"format": "tncg15-scene", "version": 4, "resolution": [8, 8],
            "camera": {"look_at": {"position": [0, -4, 2], "target": [0, 0, 0]}},
            "textures": textures,
            "materials": [{"name": "Textured", "color": [0.8, 0.8, 0.8], "color_texture": color_texture},
                          {"name": "Lamp", "color": [0, 0, 0], "emission": [2, 2, 2],
                           "emission_texture": {"texture": 0, "extension": "CLIP", "scale": [2, 2, 2]}}],
            "meshes": [{"name": "Card", "vertices": QUAD, "triangles": [[0, 1, 2], [0, 2, 3]],
                        "material": "Textured", "uvs": "@card_uvs"}]}
    arrays = dict(arrays or {}, card_uvs=np.array([[0, 0], [1, 0], [1, 1], [0, 0], [1, 1], [0, 1]], float))
    np.savez(tmp_path / f"{name}.npz", **arrays)
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(data))
    return str(path)


def test_hand_written_textures_round_trip_through_scene_files(tmp_path):
    (tmp_path / "images").mkdir()
    bytes_ = np.arange(2 * 3 * 4, dtype=np.uint8).reshape(2, 3, 4)
    grey = np.linspace(0, 1, 6, dtype=np.float32).reshape(2, 3)           # 2-D: one channel
    path = write_scene(tmp_path, [
        {"name": "Bytes", "pixels": "@bytes", "colorspace": "sRGB"},
        {"name": "Checker", "path": "images/checker.png", "colorspace": "Non-Color"},
        {"name": "Grey", "pixels": "@grey", "is_float": True},
        {"name": "Inline", "pixels": [[[0.25, 0.5, 1.0]]], "colorspace": "Linear"}],
        {"texture": "Checker", "interpolation": "Closest", "extension": "MIRROR", "scale": [1, 0.5, 0.25],
         "node": "Image Texture.001", "uv_map": "UVMap"},
        arrays={"bytes": bytes_, "grey": grey})
    scene = load_scene(path)
    names = [t.name for t in scene.textures]
    assert names == ["Bytes", "Checker", "Grey", "Inline"]
    assert scene.textures[0].pixels.dtype == np.uint8 and np.array_equal(scene.textures[0].pixels, bytes_)
    assert scene.textures[1].path == str(tmp_path / "images" / "checker.png")    # relative to the file
    assert scene.textures[1].pixels is None and scene.textures[1].colorspace == "Non-Color"
    assert scene.textures[2].pixels.shape == (2, 3, 1) and scene.textures[2].is_float
    assert scene.textures[3].pixels.dtype == np.float32 and scene.textures[3].colorspace == "Linear"
    assert scene.textures[0].colorspace == "sRGB" and not scene.textures[0].is_float
    textured, lamp = scene.materials
    assert textured.color_texture == TextureSlot(1, "Closest", "MIRROR", (1.0, 0.5, 0.25), "Image Texture.001",
                                                 "UVMap")
    assert lamp.emission_texture == TextureSlot(0, "Linear", "CLIP", (2.0, 2.0, 2.0), "", "")
    assert lamp.color_texture is None and textured.emission_texture is None
    assert any("image 'Checker'" in w and "file not found" in w for w in scene.validate())   # no PNG there

    again_path = str(tmp_path / "again.json")
    save_scene(scene, again_path)
    again = load_scene(again_path)
    for a, b in zip(scene.textures, again.textures):
        assert (a.name, a.path, a.colorspace, a.is_float) == (b.name, b.path, b.colorspace, b.is_float)
        assert (a.pixels is None and b.pixels is None) or (a.pixels.dtype == b.pixels.dtype
                                                           and np.array_equal(a.pixels, b.pixels))
    assert [(m.color_texture, m.emission_texture) for m in again.materials] == [
        (m.color_texture, m.emission_texture) for m in scene.materials]


def test_textures_json_writes_bytes_as_bytes_and_the_rest_as_float32():
    class Scene:
        textures = load_textures({"textures": [{"name": "b", "pixels": "@b"}, {"name": "f", "pixels": "@f"},
                                               {"name": "p", "path": "/abs/p.png"}]},
                                 {"b": np.ones((1, 1, 3), np.uint8), "f": np.ones((1, 1, 3), np.float64)})
    arrays = {}
    out = textures_json(Scene, arrays)
    assert [e.get("pixels", e.get("path")) for e in out] == ["@texture0_pixels", "@texture1_pixels", "/abs/p.png"]
    assert arrays["texture0_pixels"].dtype == np.uint8 and arrays["texture1_pixels"].dtype == np.float32
    assert sorted(arrays) == ["texture0_pixels", "texture1_pixels"]


def test_slot_json_round_trip():
    slot = TextureSlot(np.int64(1), "Closest", "EXTEND", (2.0, 3.0, 4.0), "node", "uv")
    entry = slot_json(slot)
    assert json.loads(json.dumps(entry)) == entry and type(entry["texture"]) is int
    textures = load_textures({"textures": [{"name": "a", "path": "a.png"}, {"name": "b", "path": "b.png"}]}, {})
    assert read_slot(Fields({"color_texture": entry}, "Material 'M'"), "color_texture", textures) == slot
    assert slot_json(None) is None
    assert read_slot(Fields({}, "Material 'M'"), "color_texture", textures) is None


def load_textures(top, arrays):
    return read_textures(Fields(top, "Scene 's'"), arrays, "/base")


@pytest.mark.parametrize("textures, arrays, message", [
    ([{"name": "Wood", "pixels": "@gone"}], {}, "Image 'Wood': pixels: array 'gone' not found in the NPZ file"),
    ([{"name": "Wood", "pixels": [1, 2, 3]}], {}, "Image 'Wood': pixels must be a (height, width, channels) array"),
    ([{"name": "Wood", "pixels": [[["a"]]]}], {}, "Image 'Wood': pixels must be a (height, width, channels) array"),
    ([{"name": "Wood", "path": "w.png", "is_float": 1}], {}, "Image 'Wood': is_float must be true or false, got 1"),
    ([{"name": "Wood"}], {}, "Image 'Wood': path is missing"),
    ([{"path": 3}], {}, "Image 'texture0': path must be a string, got 3"),
    (["Wood"], {}, "Image #0: must be a JSON object, got 'Wood'"),
])
def test_bad_image_entries_name_the_image(textures, arrays, message):
    with pytest.raises(SceneError) as error:
        load_textures({"textures": textures}, arrays)
    assert message in str(error.value)


@pytest.mark.parametrize("slot, message", [
    ({"texture": 5}, "Material 'Textured': color_texture: texture index 5 out of range"),
    ({"texture": "Nope"}, "Material 'Textured': color_texture: unknown texture 'Nope'"),
    ({"texture": 0, "scale": [1, 1]}, "Material 'Textured': color_texture: scale must be 3 numbers"),
    ({}, "Material 'Textured': color_texture: texture is missing"),
])
def test_bad_slots_in_a_scene_file_name_the_material(tmp_path, slot, message):
    path = write_scene(tmp_path, [{"name": "Checker", "pixels": [[[1, 1, 1]]]}], slot)
    with pytest.raises(SceneError) as error:
        load_scene(path)
    assert message in str(error.value)
