"""Validation errors name the object; scene files round-trip; the camera matches Blender."""
import json
import re

import numpy as np
import pytest

from engine import RenderSettings, render
from engine.scene.camera_rays import camera_rays
from engine.scene.builtin import cornell_scene
from engine.scene.model import Camera, Material, Quad, Scene, Sphere, TriangleMesh
from engine.core.errors import SceneError
from engine.scene.files import load_scene, save_scene


def base_scene(**kw):
    return Scene(Camera.look_at((0, -5, 0), (0, 0, 0)),
                 [Material("White"), Material("Lamp", color=(0, 0, 0), emission=(1, 1, 1))], **kw)


@pytest.mark.parametrize("make, message", [
    (lambda: base_scene(spheres=[Sphere("Ball", (0, 0, 0), 0.0, 0)]), "Object 'Ball': sphere radius"),
    (lambda: base_scene(spheres=[Sphere("Ball", (np.nan, 0, 0), 1.0, 0)]), "Object 'Ball': sphere centre"),
    (lambda: base_scene(meshes=[TriangleMesh("Suzanne", np.array([[0, 0, np.inf], [1, 0, 0], [0, 1, 0]]),
                                             np.array([[0, 1, 2]]), [0])]), "Object 'Suzanne': 1 vertices"),
    (lambda: base_scene(quads=[Quad("Card", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0.5], [0, 1, 0]]), 0)]),
     "Object 'Card': quad is not planar"),
    (lambda: base_scene(quads=[Quad("Card", np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]), 0)]),
     "Object 'Card': quad is degenerate"),
    (lambda: base_scene(meshes=[TriangleMesh("Lamp", np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]]),
                                             np.array([[0, 1, 2]]), [1])]), "Object 'Lamp': emitter has zero area"),
    (lambda: Scene(None, [Material("m")], name="Shot"), "Scene 'Shot': no camera"),
    (lambda: base_scene(resolution=(0, 10)), "resolution must be positive"),
])
def test_validation_names_the_object(make, message):
    scene = make()
    with pytest.raises(SceneError, match=message.replace("(", r"\(")):
        scene.validate()


def test_degenerate_triangles_are_dropped_with_one_counted_warning():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], float)
    mesh = TriangleMesh("Mixed", v, np.array([[0, 1, 2], [0, 1, 3], [1, 1, 2]]), [0, 0, 0])
    scene = base_scene(meshes=[mesh], background=(1, 1, 1))
    warnings = scene.validate()
    assert "Object 'Mixed': 2 degenerate triangle(s) dropped" in warnings
    assert len(mesh.triangles) == 1


def test_render_rejects_an_invalid_scene_before_tracing():
    scene = base_scene(spheres=[Sphere("Ball", (0, 0, 0), -1.0, 0)])
    with pytest.raises(SceneError, match="Ball"):
        render(scene, RenderSettings(samples=1), log=lambda *a: None)


def test_scene_file_round_trip(tmp_path):
    scene = cornell_scene((32, 24))
    path = str(tmp_path / "cornell.json")
    save_scene(scene, path)
    again = load_scene(path)
    assert again.resolution == (32, 24)
    assert [m.name for m in again.materials] == [m.name for m in scene.materials]
    assert sum(len(m.triangles) for m in again.meshes) == sum(len(m.triangles) for m in scene.meshes)
    a = render(scene, RenderSettings(samples=2, seed=3), log=lambda *a: None)
    b = render(again, RenderSettings(samples=2, seed=3), log=lambda *a: None)
    assert np.array_equal(a.image, b.image)


def test_scene_file_round_trip_keeps_area_lights_and_their_visibility(tmp_path):
    from engine.scene.model import AreaLight
    scene = cornell_scene((16, 16))
    disk = np.stack([0.2 * np.cos(np.linspace(0, -2 * np.pi, 12, endpoint=False)),
                     0.2 * np.sin(np.linspace(0, -2 * np.pi, 12, endpoint=False)), np.full(12, 1.9)], axis=1)
    scene.lights = [AreaLight("Disk", disk, (3.0, 2.0, 1.0), visible_camera=True, visible_glossy=False),
                    AreaLight("Panel", disk[:4] + [0, 0, -0.1], (1.0, 1.0, 1.0), two_sided=True, lights_diffuse=False)]
    path = str(tmp_path / "lit.json")
    save_scene(scene, path)
    again = load_scene(path)
    assert [(l.name, l.radiance, l.two_sided, l.visible_camera, l.visible_glossy, l.lights_diffuse)
            for l in again.lights] == [("Disk", (3.0, 2.0, 1.0), False, True, False, True),
                                        ("Panel", (1.0, 1.0, 1.0), True, False, True, False)]
    assert np.array_equal(again.lights[0].vertices, disk)
    a = render(scene, RenderSettings(samples=2, seed=3), log=lambda *a: None)
    b = render(again, RenderSettings(samples=2, seed=3), log=lambda *a: None)
    assert np.array_equal(a.image, b.image)


def test_scene_file_round_trip_keeps_point_spot_and_sun_lights(tmp_path):
    from engine.scene.model import PointLight, SunLight
    scene = cornell_scene((16, 16))
    scene.points = [PointLight("Bulb", (0.1, 0.2, 1.5), (2.0, 1.0, 0.5), 0.05),
                    PointLight("Spot", (0.0, 0.0, 1.8), (9.0, 9.0, 9.0), 0.02, spot_size=0.9, spot_blend=0.3,
                               spot_direction=(0.1, 0.0, -1.0), spot_falloff="cosine-smoothstep",
                               visible_glossy=False)]
    scene.suns = [SunLight("Sun", (0.3, 0.2, -1.0), (1.0, 0.9, 0.8), 0.05, lights_diffuse=False,
                           visible_transmission=False),
                  SunLight("Sky's sun", (-0.3, 0.2, -1.0), (3.0, 2.9, 2.8), 0.01, sky_disc=True)]
    path = str(tmp_path / "lamps.json")
    save_scene(scene, path)
    again = load_scene(path)
    assert again.points == scene.points and again.suns == scene.suns
    a = render(scene, RenderSettings(samples=2, seed=3), log=lambda *a: None)
    b = render(again, RenderSettings(samples=2, seed=3), log=lambda *a: None)
    assert np.array_equal(a.image, b.image)


def test_scene_file_of_a_newer_format_is_refused(tmp_path):
    path = tmp_path / "future.json"
    path.write_text(json.dumps({"format": "tncg15-scene", "version": 99, "materials": [{"name": "m"}]}))
    with pytest.raises(SceneError, match="format version 99"):
        load_scene(str(path))


def test_scene_file_errors_name_the_problem(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "tncg15-scene", "materials": [{"name": "m"}],
                               "spheres": [{"name": "Ball", "center": [0, 0, 0], "radius": 1, "material": "nope"}]}))
    with pytest.raises(SceneError, match="Object 'Ball': unknown material 'nope'"):
        load_scene(str(bad))
    with pytest.raises(SceneError, match="not a tncg15-scene"):
        (tmp_path / "x.json").write_text("{}")
        load_scene(str(tmp_path / "x.json"))


@pytest.mark.parametrize("w, h, fit, expect_axis", [(200, 100, "AUTO", 0), (100, 200, "AUTO", 1),
                                                    (100, 200, "HORIZONTAL", 0), (200, 100, "VERTICAL", 1)])
def test_camera_field_of_view_follows_blender_sensor_fit(w, h, fit, expect_axis):
    cam = Camera(matrix=np.eye(4), lens=50.0, sensor_width=36.0, sensor_height=24.0, sensor_fit=fit)
    # Rays through the image edges along the fitted axis.
    if expect_axis == 0:
        _, d = camera_rays(cam, w, h, np.array([0.0, float(w)]), np.array([h / 2, h / 2]))
        d = d.T                                    # rows -> (N, 3)
        slope = d[:, 0] / -d[:, 2]
    else:
        _, d = camera_rays(cam, w, h, np.array([w / 2, w / 2]), np.array([0.0, float(h)]))
        d = d.T
        slope = d[:, 1] / -d[:, 2]
    sensor = 24.0 if fit == "VERTICAL" else 36.0
    assert np.abs(slope).tolist() == pytest.approx([sensor / 2 / 50.0] * 2, rel=1e-12)
    assert slope[0] * slope[1] < 0


def test_camera_shift_and_orientation():
    cam = Camera.look_at((0, -5, 1), (0, 0, 1), lens=50.0, shift_x=0.1)
    o, d = camera_rays(cam, 100, 100, np.array([50.0]), np.array([50.0]))
    o, d = o.T, d.T
    assert np.allclose(o, [0, -5, 1])
    # Looking along +y; shift 0.1 of the 36 mm sensor at lens 50 moves the centre ray right (+x).
    assert d[0, 1] > 0 and d[0, 0] / d[0, 1] == pytest.approx(0.1 * 36 / 50, rel=1e-12)


@pytest.mark.parametrize("name, corners, material", [
    ("Bent", [(0, 0, 0), (1, 0, 0), (1, 1, 0.1), (0, 1, 0)], 0), ("Crossed", [(0, 0, 0), (1, 1, 0), (1, 0, 0), (0, 1, 0)], 0),
    ("Flat", [(0, 0, 0)] * 4, 0), ("Nan", [(np.nan, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], 0),
    ("Three", [(0, 0, 0), (1, 0, 0), (1, 1, 0)], 0), ("Twelve", list(range(12)), 0),
    ("Huge", [(0, 0, 0), (2e30, 0, 0), (2e30, 2e30, 0), (0, 2e30, 0)], 0),
    ("Unknown material", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], 9)])
def test_quads_checked_all_at_once_fail_as_one_by_one(name, corners, material):
    """Scene.validate checks every quad at once (engine/scene/checks.py validate_quads): a bad quad
    among good ones gives the message Quad.validate gives it alone."""
    good = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], float)
    bad = Quad(name, np.array(corners, dtype=float), material)
    with pytest.raises(SceneError) as alone:
        Quad(name, np.array(corners, dtype=float), material).validate(2)
    with pytest.raises(SceneError, match=re.escape(str(alone.value))):
        base_scene(quads=[Quad("a", good, 0), bad, Quad("b", good + 2, 0)]).validate()
    assert base_scene(quads=[Quad("a", good, 0), Quad("b", good + 2, 1)]).validate() is not None


def test_scene_file_round_trip_keeps_blender_3_sharp_closures(tmp_path):
    """A 3.x Sharp mirror stays sharp under Filter Glossy after a save and load (control: a mirror
    without the flag stays blurrable, and files without the key load unflagged)."""
    from engine.scene.model import MIRROR
    scene = base_scene()
    scene.materials += [Material("Sharp", kind=MIRROR, sharp_closure=True), Material("Plain", kind=MIRROR)]
    path = str(tmp_path / "sharp.json")
    save_scene(scene, path)
    entries = {m["name"]: m for m in json.load(open(path))["materials"]}
    assert entries["Sharp"]["sharp_closure"] is True and "sharp_closure" not in entries["Plain"]
    again = {m.name: m.sharp_closure for m in load_scene(path).materials}
    assert again == {"White": False, "Lamp": False, "Sharp": True, "Plain": False}
    entries["Plain"]["sharp_closure"] = "yes"
    json.dump({**json.load(open(path)), "materials": list(entries.values())}, open(path, "w"))
    with pytest.raises(SceneError, match="Material 'Plain': sharp_closure must be true or false"):
        load_scene(path)
