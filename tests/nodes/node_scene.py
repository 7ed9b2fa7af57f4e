"""A node-graph room for the Cycles agreement tests of tests/nodes/test_agreement_nodes.py (bpy 5.0 or
3.4): the floor's Principled BSDF takes its Base Color from an Image Texture through Texture
Coordinate (Object) -> Mapping and its Roughness from the same image at its implicit coordinates
(Generated); a smooth sphere's Diffuse colour is its Geometry Normal through a Mapping (x 0.5 + 0.5);
the lamp's Emission colour comes from Texture Coordinate Generated."""
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "sample_blends"))

import make_samples as ms  # noqa: E402

import bpy  # noqa: E402

SCALE = (2.0, 2.0, 2.0)


def build(path, resolution=(64, 64)):
    scene = ms.reset()
    mats = dict(white=ms.diffuse("White", (0.73, 0.73, 0.73)), red=ms.diffuse("Red", (0.65, 0.05, 0.05)),
                green=ms.diffuse("Green", (0.12, 0.45, 0.15)), light=lamp_material())
    ms.room(scene, mats, light_size=0.6)
    floor = bpy.data.objects["Floor"]
    floor.data.materials.clear()
    floor.data.materials.append(floor_material())
    ms.mesh_object(scene, "Ball", lambda bm: ms.uv_sphere(bm, 0.35), normal_material(),
                   location=(0.2, 0.1, 0.5), smooth=True)
    ms.camera(scene)
    ms.black_world(scene)
    ms.settings(scene, resolution)
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return path


def image():
    img = bpy.data.images.new("Grid", 64, 64)
    img.generated_type = "COLOR_GRID"
    return img


def floor_material():
    mat, nodes, links, out = ms.empty_material("NodeFloor")
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    for key, value in (("Specular IOR Level", 0.5), ("Metallic", 0.0)):
        if key in bsdf.inputs:
            bsdf.inputs[key].default_value = value
    coords = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.name = "Mapping"
    mapping.inputs["Scale"].default_value = SCALE
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(25))
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image()
    tex.interpolation = "Closest"
    rough = nodes.new("ShaderNodeTexImage")
    rough.image = tex.image
    links.new(coords.outputs["Object"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    links.new(coords.outputs["Generated"], rough.inputs["Vector"])
    links.new(rough.outputs["Color"], bsdf.inputs["Roughness"])
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def normal_material():
    mat, nodes, links, out = ms.empty_material("NodeBall")
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    geo = nodes.new("ShaderNodeNewGeometry")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (0.5, 0.5, 0.5)
    mapping.inputs["Location"].default_value = (0.5, 0.5, 0.5)
    links.new(geo.outputs["Normal"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], bsdf.inputs["Color"])
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def lamp_material():
    mat, nodes, links, out = ms.empty_material("NodeLamp")
    em = nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 14.0
    coords = nodes.new("ShaderNodeTexCoord")
    links.new(coords.outputs["Generated"], em.inputs["Color"])
    links.new(em.outputs[0], out.inputs["Surface"])
    return mat


if __name__ == "__main__":              # blender -b --python tests/nodes/node_scene.py -- OUT.blend
    build(sys.argv[sys.argv.index("--") + 1])
