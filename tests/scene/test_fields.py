"""engine/scene/fields.py: every wrong type or shape in a scene file is one SceneError naming the object
and the field; right values come back converted."""
import json

import numpy as np
import pytest

from engine.core.errors import SceneError
from engine.scene.fields import Fields, describe, is_integer, is_number
from engine.scene.files import load_scene

OWNER = "Material 'Red'"


@pytest.mark.parametrize("call, data, message", [
    (lambda f: f.text("kind"), {"kind": 3}, "kind must be a string, got 3"),
    (lambda f: f.number("ior"), {"ior": "1.5"}, "ior must be a number, got '1.5'"),
    (lambda f: f.number("ior"), {"ior": True}, "ior must be a number, got True"),
    (lambda f: f.numbers("color", 3), {"color": "red"}, "color must be 3 numbers, got 'red'"),
    (lambda f: f.numbers("color", 3), {"color": [1, 0]}, "color must be 3 numbers, got [1, 0]"),
    (lambda f: f.numbers("color", 3), {"color": [1, 0, None]}, "color must be 3 numbers, got [1, 0, None]"),
    (lambda f: f.integers("resolution", 2), {"resolution": [64, 4.5]}, "resolution must be 2 integers"),
    (lambda f: f.integers("resolution", 2), {"resolution": [64, False]}, "resolution must be 2 integers"),
    (lambda f: f.matrix("matrix", 2, 2), {"matrix": [[1, 0], [0]]}, "matrix must be 2 rows of 2 numbers"),
    (lambda f: f.objects("meshes"), {"meshes": {}}, "meshes must be a list, got {}"),
    (lambda f: f.get("name"), {}, "name is missing"),
    (lambda f: f.array("vertices", {}, 3, False), {"vertices": [[0, 0]]}, "vertices must be a list of [x, y, z] numbers"),
    (lambda f: f.array("vertices", {}, 3, False), {"vertices": [[0, 0, 0], [1, 1]]}, "vertices must be a list of"),
    (lambda f: f.array("vertices", {}, 3, False), {"vertices": [[1j, 0, 0]]}, "vertices must be a list of"),
    (lambda f: f.array("ids", {}, None, True), {"ids": [0.5, 1]}, "ids must be a list of integers"),
    (lambda f: f.array("ids", {}, None, True), {"ids": [True, False]}, "ids must be a list of integers"),
    (lambda f: f.array("ids", {}, None, True), {"ids": "ids"}, "ids must be a list of integers or \"@name\""),
    (lambda f: f.array("ids", {}, None, True), {"ids": "@gone"}, "ids: array 'gone' not found in the NPZ file"),
    (lambda f: f.array("ids", {"a": np.zeros((2, 2), np.int64)}, None, True), {"ids": "@a"},
     "ids must be a list of integers, got 'an array of int64 with shape (2, 2)'"),
])
def test_wrong_fields_are_errors_naming_the_object_and_field(call, data, message):
    with pytest.raises(SceneError) as error:
        call(Fields(data, OWNER))
    assert str(error.value).startswith(f"{OWNER}: ")
    assert message in str(error.value)


def test_not_an_object():
    with pytest.raises(SceneError, match=r"^Object 'Floor': must be a JSON object, got \[1, 2\]$"):
        Fields([1, 2], "Object 'Floor'")


def test_right_fields_come_back_converted():
    arrays = {"v": np.arange(6, dtype=np.float32).reshape(2, 3)}
    f = Fields({"kind": "glass", "ior": 2, "color": [1, 0, 0.5], "resolution": [64, 48],
                "matrix": [[1, 2], [3, 4]], "vertices": "@v", "ids": [2, 0], "empty": []}, OWNER)
    assert f.text("kind") == "glass"
    assert f.number("ior") == 2.0 and isinstance(f.number("ior"), float)
    assert f.numbers("color", 3) == (1.0, 0.0, 0.5)
    assert f.integers("resolution", 2) == (64, 48)
    assert f.matrix("matrix", 2, 2).tolist() == [[1.0, 2.0], [3.0, 4.0]]
    v = f.array("vertices", arrays, 3, integer=False)
    assert v.dtype == np.float64 and np.array_equal(v, arrays["v"])
    ids = f.array("ids", arrays, None, integer=True)
    assert ids.dtype == np.int64 and ids.tolist() == [2, 0]
    assert f.array("empty", arrays, 3, integer=True).shape == (0, 3)
    assert f.objects("meshes") == [] and f.number("missing", 0.5) == 0.5 and "kind" in f


def test_helpers():
    assert is_number(1) and is_number(1.5) and is_number(np.float32(2)) and not is_number(True)
    assert is_integer(3) and is_integer(np.int64(3)) and not is_integer(3.0) and not is_integer(False)
    assert describe("x" * 100) == repr("x" * 100)[:37] + "..." and describe([1]) == "[1]"


def test_scene_file_errors_name_the_object(tmp_path):
    """Through engine/scene/files.py: the owner is the object's own name from the file."""
    base = {"format": "tncg15-scene", "version": 4, "materials": [{"name": "White"}],
            "camera": {"look_at": {"position": [0, -5, 0], "target": [0, 0, 0]}}}
    cases = [
        ({"spheres": [{"name": "Ball", "center": [0, 0], "radius": 1}]}, "Object 'Ball': center must be 3 numbers"),
        ({"materials": [{"name": "Red", "color": "red"}]}, "Material 'Red': color must be 3 numbers, got 'red'"),
        ({"lights": [{"name": "Lamp", "vertices": [[0, 0, 1]], "radiance": [1, 1, 1], "two_sided": "yes"}]},
         "Light 'Lamp': two_sided must be true or false, got 'yes'"),
        ({"camera": {"look_at": {"position": [0, -5, 0]}}}, "Camera 'Camera': look_at: target is missing"),
        ({"materials": [{"color": [1, 1, 1]}]}, "Material #0: name is missing"),
    ]
    for change, message in cases:
        path = tmp_path / "scene.json"
        path.write_text(json.dumps(dict(base, **change)))
        with pytest.raises(SceneError) as error:
            load_scene(str(path))
        assert message in str(error.value), (change, str(error.value))


HUGE = 10 ** 400                              # JSON integers have no bound; float64 ends near 1.8e308


@pytest.mark.parametrize("call, data", [
    (lambda f: f.number("ior"), {"ior": HUGE}),
    (lambda f: f.numbers("color", 3), {"color": [0, -HUGE, 0]}),
    (lambda f: f.matrix("matrix", 2, 2), {"matrix": [[1, 0], [0, HUGE]]}),
    (lambda f: f.array("vertices", {}, 3, False), {"vertices": [[0, 0, HUGE]]}),
])
def test_integers_beyond_float64_are_errors_naming_the_field(call, data):
    """Was an OverflowError traceback (int too large to convert to float)."""
    with pytest.raises(SceneError, match=f"^{OWNER}: "):
        call(Fields(data, OWNER))


def test_a_400_digit_integer_anywhere_in_a_scene_file_is_a_scene_error(tmp_path):
    """Every number of a saved scene replaced in turn by a 400-digit integer (the fuzzer's find), and
    one by 5,000 digits (past Python's int_max_str_digits, a ValueError inside json.load)."""
    import re
    from engine.scene.files import save_scene
    from engine.scene.model import AreaLight, PointLight, Sphere, SunLight
    from tests.scenes import diffuse_box_scene
    scene = diffuse_box_scene((8, 8))
    scene.spheres.append(Sphere("Ball", (0.0, 0.5, 0.5), 0.2, 0))
    scene.lights.append(AreaLight("Lamp", np.array([(0, 0, 1.9), (0.1, 0, 1.9), (0, 0.1, 1.9)]), (1, 1, 1)))
    scene.points.append(PointLight("Bulb", (0.0, 0.0, 1.0), (1.0, 1.0, 1.0), 0.1))
    scene.suns.append(SunLight("Sun", (0.0, 0.0, -1.0), (1.0, 1.0, 1.0)))
    save_scene(scene, str(tmp_path / "scene.json"))
    text = (tmp_path / "scene.json").read_text()
    numbers = list(re.finditer(r"(?<![\w.\"])-?\d+(\.\d+)?", text))
    assert len(numbers) > 80
    for digits, found in [(400, m) for m in numbers] + [(5000, numbers[0])]:
        path = tmp_path / "scene.json"
        path.write_text(text[:found.start()] + "9" * digits + text[found.end():])
        try:
            load_scene(str(path)).validate()
        except SceneError:
            pass
