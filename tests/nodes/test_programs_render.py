"""Node programs reach the BSDFs (engine/materials/textures.py HitTextures): a colour on a mesh and on an
analytic sphere, a float input, a Mix Shader factor and an emission, rendered small; the same scene
with the programs dropped renders otherwise, and a scene without programs is unchanged."""
import dataclasses

import numpy as np

from engine.api import render
from engine.core.settings import RenderSettings
from engine.scene.builtin import cornell_scene
from engine.scene.model import Material, Mix, MixFactor, MixLeaf
from engine.scene.programs import Link, Program, ProgramNode

SETTINGS = dict(samples=2, parallelism="threads", seed=3)


def normal_colour():
    return Program([ProgramNode("ShaderNodeNewGeometry", "Geometry", {"_outputs": ["Normal"]}),
                    ProgramNode("ShaderNodeMapping", "Mapping", {"vector_type": "POINT", "_outputs": ["Vector"]},
                                {"Vector": Link(0, "Normal", "VECTOR", "VECTOR"), "Scale": (0.5, 0.5, 0.5),
                                 "Location": (0.5, 0.5, 0.5)})],
                   (1, "Vector", "VECTOR"), "RGBA")


def height(target="VALUE"):
    return Program([ProgramNode("ShaderNodeTexCoord", "Coords", {"_outputs": ["Generated"]})],
                   (0, "Generated", "VECTOR"), target)


def image(scene):
    return render(scene, RenderSettings(**SETTINGS), log=lambda *a: None).image


def with_programs(scene):
    mats = list(scene.materials)
    by = {m.name: i for i, m in enumerate(mats)}
    mats[by["White"]] = dataclasses.replace(mats[by["White"]], programs={"color": normal_colour()})
    mats[by["Blue"]] = dataclasses.replace(mats[by["Blue"]], kind="mix", mix=Mix([
        MixLeaf(Material("leaf diffuse", color=(0.9, 0.2, 0.1), programs={"color": normal_colour()}),
                [MixFactor(kind="program", program=height(), invert=True, node="Coords")]),
        MixLeaf(Material("leaf glossy", kind="glossy", roughness=0.3, programs={"roughness": height()}),
                [MixFactor(kind="program", program=height(), node="Coords")])]))
    mats[by["Light"]] = dataclasses.replace(mats[by["Light"]], programs={"emission": Program(
        height("RGBA").nodes + [ProgramNode("TNCG15Scale", "", {}, {"Color": Link(0, "Generated", "VECTOR", "RGBA"),
                                                                   "Strength": 12.0})], (1, "Color", "RGBA"))})
    sphere = next(s for s in scene.spheres)
    mats.append(Material("Sphere colour", programs={"color": normal_colour()}))
    spheres = [dataclasses.replace(sphere, material_id=len(mats) - 1)] + list(scene.spheres[1:])
    return dataclasses.replace(scene, materials=mats, spheres=spheres)


def test_programs_render_and_change_the_image():
    scene = cornell_scene((24, 24))
    programmed = with_programs(scene)
    programmed.validate()
    a = image(programmed)
    assert np.isfinite(a).all() and a.mean() > 0
    dropped = dataclasses.replace(programmed, materials=[dataclasses.replace(m, programs={})
                                                         for m in programmed.materials])
    assert not np.allclose(a, image(dropped))


def test_programs_and_object_data_round_trip_through_scene_files(tmp_path):
    from engine.scene.files import load_scene, save_scene
    scene = with_programs(cornell_scene((16, 16)))
    meshes = [dataclasses.replace(m, object_matrix=np.eye(4), texspace=((0.0, 0.0, 0.0), (1.0, 2.0, 3.0)),
                                  object_random=0.25) for m in scene.meshes]
    scene = dataclasses.replace(scene, meshes=meshes)
    path = str(tmp_path / "s.json")
    save_scene(scene, path)
    again = load_scene(path)
    assert [m.programs for m in again.materials] == [m.programs for m in scene.materials]
    assert again.materials[[m.kind for m in again.materials].index("mix")].mix.leaves[0].factors[0].program == height()
    assert again.meshes[0].texspace == ((0.0, 0.0, 0.0), (1.0, 2.0, 3.0)) and again.meshes[0].object_random == 0.25
    assert np.array_equal(image(again), image(scene))
