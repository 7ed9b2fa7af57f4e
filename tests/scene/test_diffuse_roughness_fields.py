"""Material.diffuse_roughness and Scene.cycles_version: validation, and scene files that store
them (diffuse_roughness only where it is not 0, so files of Lambertian materials stay the same)."""
import json

import pytest

from engine.core.errors import SceneError
from engine.scene.files import load_scene, save_scene
from engine.scene.model import Camera, Material, Scene, Sphere


def scene(**kw):
    mats = [Material("Clay", diffuse_roughness=kw.pop("roughness", 0.0)), Material("Lamp", emission=(1, 1, 1))]
    return Scene(Camera.look_at((0, -4, 0), (0, 0, 0)), mats, spheres=[Sphere("Ball", (0, 0, 0), 1.0, 0)],
                 resolution=(8, 8), **kw)


@pytest.mark.parametrize("value", [-0.1, 1.5, float("nan"), "0.5", True])
def test_diffuse_roughness_outside_0_to_1_is_refused(value):
    with pytest.raises(SceneError, match="diffuse roughness"):
        scene(roughness=value).validate()


@pytest.mark.parametrize("value", [(4,), (4, 3, 1), (4.0, 3), "4.3", (-1, 0), (True, 3)])
def test_cycles_version_must_be_two_integers(value):
    with pytest.raises(SceneError, match="cycles_version"):
        scene(cycles_version=value).validate()


def test_files_store_both_and_old_files_read_the_defaults(tmp_path):
    path = str(tmp_path / "s.json")
    save_scene(scene(roughness=0.7, cycles_version=(3, 6)), path)
    data = json.load(open(path))
    assert data["cycles_version"] == [3, 6]
    assert data["materials"][0]["diffuse_roughness"] == 0.7 and "diffuse_roughness" not in data["materials"][1]
    back = load_scene(path)
    assert back.cycles_version == (3, 6) and back.materials[0].diffuse_roughness == 0.7
    del data["cycles_version"], data["materials"][0]["diffuse_roughness"]
    json.dump(data, open(path, "w"))
    old = load_scene(path)
    assert old.cycles_version == (5, 0) and old.materials[0].diffuse_roughness == 0.0
